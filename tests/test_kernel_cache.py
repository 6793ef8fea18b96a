"""Cached numba kernels are dropped when the package's sources change
(baker/kernel_cache.py): numba checks only the file defining a kernel,
and the sweep inlines the visibility rule from another file."""
import os

from baker.kernel_cache import sync


def _package(root):
    os.makedirs(os.path.join(root, "solve", "__pycache__"))
    for name, text in (("__init__.py", ""), ("solve/sweep.py", "x = 1\n"), ("solve/visibility.py", "TAU = 0.1\n")):
        with open(os.path.join(root, name), "w") as f:
            f.write(text)
    for name in ("sweep._sweep-1.py311.nbi", "sweep._sweep-1.py311.1.nbc"):
        open(os.path.join(root, "solve", "__pycache__", name), "w").close()


def _cached(root):
    return sorted(os.listdir(os.path.join(root, "solve", "__pycache__")))


def test_kernels_stay_while_the_sources_are_unchanged(tmp_path):
    root = str(tmp_path / "pkg")
    _package(root)
    sync(root)  # first sight: the stamp is written (and the unknown cache dropped)
    open(os.path.join(root, "solve", "__pycache__", "sweep._sweep-1.py311.nbi"), "w").close()
    assert sync(root) is False
    assert "sweep._sweep-1.py311.nbi" in _cached(root)


def test_a_changed_callee_drops_the_callers_kernels(tmp_path):
    root = str(tmp_path / "pkg")
    _package(root)
    sync(root)
    open(os.path.join(root, "solve", "__pycache__", "sweep._sweep-1.py311.nbi"), "w").close()
    with open(os.path.join(root, "solve", "visibility.py"), "w") as f:
        f.write("TAU = 0.2\n")  # sweep.py untouched: numba alone would keep the old sweep
    assert sync(root) is True
    assert not [n for n in _cached(root) if n.endswith((".nbi", ".nbc"))]
    assert sync(root) is False  # and the new stamp holds


CHILD = r"""
import importlib.util, os, sys, time
spec = importlib.util.spec_from_file_location("kernel_cache", sys.argv[3])   # alone: the package's import is slow
kc = importlib.util.module_from_spec(spec)
spec.loader.exec_module(kc)
root, go = sys.argv[1], sys.argv[2]
calls, walk = [0], os.walk


def slow_walk(*args, **kwargs):   # the n-th process reaches its drop n tenths of a second after its check
    calls[0] += 1
    if calls[0] == 2:
        time.sleep(0.1 * int(sys.argv[4]))
    return walk(*args, **kwargs)


os.walk = slow_walk
while not os.path.exists(go):
    time.sleep(0.001)
dropped = kc.sync(root)
# this process's compile, written after its own check: no later check may drop it
open(os.path.join(root, "solve", "__pycache__", f"k{os.getpid()}.nbi"), "w").close()
print(int(dropped), os.getpid())
"""


def test_processes_starting_at_once_drop_the_kernels_once(tmp_path):
    """Eight processes released at once after the sources changed (a
    bake's workers, parallel test runs), each slowed between its check of
    the stamp and its drop by a different delay: one drops the old
    kernels, the others find the new stamp (the check, the drop and the
    stamp happen under a file lock), and no kernel a process wrote after
    its own check is deleted by another's (without the lock every process
    saw the old stamp, and the slow ones deleted the fast ones' kernels)."""
    import subprocess
    import sys
    root = str(tmp_path / "pkg")
    _package(root)
    sync(root)
    with open(os.path.join(root, "solve", "visibility.py"), "w") as f:
        f.write("TAU = 0.3\n")
    for name in ("sweep._sweep-1.py311.nbi", "sweep._sweep-1.py311.1.nbc"):
        open(os.path.join(root, "solve", "__pycache__", name), "w").close()
    go = str(tmp_path / "go")
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    import baker.kernel_cache
    procs = [subprocess.Popen([sys.executable, "-c", CHILD, root, go, baker.kernel_cache.__file__, str(i)],
                              stdout=subprocess.PIPE, text=True, cwd=here) for i in range(8)]
    import time
    time.sleep(1.0)   # every child imported and waiting
    open(go, "w").close()
    out = [p.communicate(timeout=120)[0].split() for p in procs]
    assert all(p.returncode == 0 for p in procs)
    assert sum(int(d) for d, _ in out) == 1
    left = _cached(root)
    assert all(f"k{pid}.nbi" in left for _, pid in out)
    assert "sweep._sweep-1.py311.nbi" not in left
