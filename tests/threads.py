"""Results must not depend on the thread count: the counts to compare and
the comparison (the pool is sized in conftest.py)."""
import os

import numba
import numpy as np


def thread_counts():
    """1, 2, 3 and every thread numba has: a result must be the same for each."""
    return sorted({1, 2, 3, numba.config.NUMBA_NUM_THREADS, os.cpu_count() or 1} &
                  set(range(1, numba.config.NUMBA_NUM_THREADS + 1)))


def same_for_any_thread_count(compute):
    """Runs compute() with each of thread_counts() threads and asserts that
    every result (an array or a tuple of arrays) is identical to the first;
    returns it."""
    before = numba.get_num_threads()
    results = []
    try:
        for n in thread_counts():
            numba.set_num_threads(n)
            results.append((n, compute()))
    finally:
        numba.set_num_threads(before)
    n0, first = results[0]
    for n, other in results[1:]:
        for a, b in zip(_arrays(first), _arrays(other)):
            np.testing.assert_array_equal(a, b, err_msg=f"{n0} vs {n} threads")
    return first


def _arrays(result):
    return result if isinstance(result, tuple) else (result,)
