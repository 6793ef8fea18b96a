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
