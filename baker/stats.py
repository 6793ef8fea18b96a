"""Timers, counters and peak memory per stage; written as JSON by --stats."""
from __future__ import annotations

import json
import os
import platform
import resource
import time
from contextlib import contextmanager


def release_freed_memory():
    """Hands freed heap memory back to the OS (glibc's malloc_trim; a no-op
    elsewhere). After a stage that frees large temporaries, glibc keeps them
    (its mmap threshold grows after large frees): resident memory would
    stay at the stage's peak for the rest of the run."""
    try:
        import ctypes
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MiB: the kernel's
    high-water mark of this program's memory (VmHWM). ru_maxrss would also
    count the parent's peak when the parent started us with vfork (as
    Python's subprocess does): a bake run by a large benchmark process
    reported the benchmark's memory."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


class Stats:
    """Stage timings (seconds), peak memory after each stage, counters."""

    def __init__(self, command: str = ""):
        self.command = command
        self.stages = {}
        self.counters = {}
        self._t0 = time.perf_counter()

    @contextmanager
    def stage(self, name: str):
        t, c = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            entry = self.stages.setdefault(name, {"seconds": 0.0, "cpu_seconds": 0.0})
            entry["seconds"] += time.perf_counter() - t
            # the process's CPU time over the stage (every thread's): over seconds, how many cores it kept busy
            entry["cpu_seconds"] += time.process_time() - c
            entry["peak_rss_mb"] = round(peak_rss_mb(), 1)

    def count(self, **values):
        self.counters.update(values)

    def as_dict(self) -> dict:
        import numba
        return {
            "command": self.command,
            "total_seconds": time.perf_counter() - self._t0,
            "stages": self.stages,
            "counters": self.counters,
            "peak_rss_mb": round(peak_rss_mb(), 1),
            "machine": {"cpus": os.cpu_count(), "threads": numba.get_num_threads(),
                        "cpu": platform.processor() or platform.machine(), "python": platform.python_version()},
        }

    def write(self, path):
        from .fileio import atomic_write

        def w(tmp):
            with open(tmp, "w") as f:
                json.dump(self.as_dict(), f, indent=2, default=_jsonable)
        atomic_write(path, w)


def _jsonable(x):
    try:
        import numpy as np
        if isinstance(x, np.generic):
            return x.item()
        if isinstance(x, np.ndarray):
            return x.tolist()
    except ImportError:
        pass
    return str(x)
