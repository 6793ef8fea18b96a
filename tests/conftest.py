"""Shared fixtures: scenes built on the fly from the generator; the thread
pool sized for the thread-count tests (tests/threads.py)."""
import os

# numba reads its pool size once, at import: make room for more threads than
# cores so that the thread-count tests can compare 1, 2, 3 and all even on a
# one- or two-core machine (the other tests use the cores there are).
os.environ.setdefault("NUMBA_NUM_THREADS", str(max(4, os.cpu_count() or 1)))

import contextlib  # noqa: E402
import io  # noqa: E402
import warnings  # noqa: E402

import numba  # noqa: E402
import pytest  # noqa: E402

from baker.errors import VoxgiWarning  # noqa: E402
from baker.scene import load_scene  # noqa: E402

numba.set_num_threads(min(os.cpu_count() or 1, numba.config.NUMBA_NUM_THREADS))


@pytest.fixture(autouse=True)
def quiet_voxgi_warnings():
    """What the test scenes hold that the baker ignores is no news (tests that
    check a warning catch it with pytest.warns)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=VoxgiWarning)
        yield


@pytest.fixture(scope="session")
def scene_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("scenes")


@pytest.fixture(scope="session")
def make_scene(scene_dir):
    """make_scene(builder, name) -> Scene: saves a GltfBuilder and loads it back."""
    cache = {}

    def make(builder, name):
        if name not in cache:
            path = os.path.join(scene_dir, name + ".glb")
            builder.save(path)
            cache[name] = load_scene(path)
        return cache[name]
    return make


@pytest.fixture(scope="session")
def cornell():
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return load_scene(os.path.join(here, "scenes", "cornell_box.glb"))


REALSCENES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "..", "shared", "realscenes")
# McGuire's Cornell box (Williams College 2011, CC BY 3.0): its short box's faces come before their `usemtl`, so
# they take the red wall's material, and every box repeats its front face as its bottom
MCGUIRE_CORNELL = os.path.join(REALSCENES, "mcguire_cornellbox", "CornellBox-Original.obj")


def need_xvfb():
    """Skips a test that opens a real window when Xvfb is not installed; on
    CI (CI=true, or scripts/test.sh's VOXGI_REQUIRE_WEB=1), where
    scripts/setup.sh installs it, its absence is a failure instead."""
    import shutil
    if shutil.which("xvfb-run"):
        return
    why = "Xvfb is not installed (scripts/setup.sh installs it)"
    if os.environ.get("CI") or os.environ.get("VOXGI_REQUIRE_WEB") == "1":
        pytest.fail(why + ", and CI must run the window tests")
    pytest.skip(why)


def skip_without_shared(path, what):
    """Skips a test whose public file (read through ../shared, never committed)
    is absent; on CI (CI=true), where ../shared lies beside the clone, its
    absence is a failure instead, so the test cannot vanish silently."""
    if os.path.exists(path):
        return
    if os.environ.get("CI"):
        pytest.fail(f"{what} ({path}) is missing on CI, where ../shared must lie beside the clone")
    pytest.skip(f"{what} is read from ../shared/realscenes, absent here")


def cli(*args, main=None):
    """(exit status, stdout, stderr) of `voxbake ARGS` (or of `main`, e.g.
    voxview's) run in this process: for the commands' tests where no
    signal is involved."""
    if main is None:
        from baker.cli import main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as e:
            code = e.code
    return code, out.getvalue(), err.getvalue()
