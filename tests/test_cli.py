"""The command line as a user meets it: refusals before any work, one-line
errors, Ctrl-C at any moment, warnings."""
import signal
import subprocess
import sys
import time
import warnings

import pytest

from baker.cli import run
from baker.config import solver_config
from baker.errors import ConfigError, VoxgiWarning


def voxbake(*args, cwd=None, timeout=300):
    return subprocess.run([sys.executable, "-m", "baker", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)


def test_bad_settings_are_refused_before_work(tmp_path):
    out = tmp_path / "x.png"
    cases = [
        (["--threads", "-3"], "argument --threads: must lie in 0..4,096"),
        (["--stats", tmp_path / "missing" / "s.json"], "output folder does not exist"),
        (["--fov", "200"], "argument --fov: must be a finite number above 0 and at most 180"),
        (["--method", "voxels", "--photons", "-1"], "argument --photons: must lie in 1.."),
        (["--method", "voxels", "--photons-per-voxel", "-2"], "argument --photons-per-voxel: must be a finite"),
        (["--method", "voxels", "--photon-smoothing", "-1"], "argument --photon-smoothing: must be a finite"),
        (["--method", "voxels", "--surface-cells", "0"], "argument --surface-cells: must lie in 1.."),
        (["--sky", "1,-1,1"], "must not be negative"),
        (["--noise", "0"], "argument --noise: must be a finite number above 0 and at most 1"),
        (["--time-limit", "-1"], "argument --time-limit: must be a finite number"),
        (["--method", "voxels", "--noise", "0.02"], "apply to --method pathtrace"),
    ]
    for extra, message in cases:
        r = voxbake("render", "cornell_box", "-o", out, *extra)
        assert r.returncode == 2 and message in r.stderr and "Traceback" not in r.stderr, (extra, r.stderr)
        assert not out.exists()


def test_absurd_resolution_is_refused_at_once(tmp_path):
    """The memory estimate costs O(triangles): a resolution or a cell size
    within the flags' ranges but far beyond the memory budget is refused
    with the estimate instead of counting 10^11 cells first (the
    subprocess's timeout is the bound; before the estimate: over 10
    minutes)."""
    for flags in (["--resolution", "60000"], ["--cell-size", "1e-5"]):
        r = voxbake("render", "cornell_box", "--method", "voxels", *flags, "-o", tmp_path / "x.png", timeout=120)
        assert r.returncode == 2 and "needs about" in r.stderr and "at least" in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "x.png").exists()


def test_unknown_setting_is_an_error():
    with pytest.raises(ConfigError, match="unknown solver setting 'photon' \\(did you mean 'photons'\\?\\)"):
        solver_config("default", photon=10)
    with pytest.raises(ValueError):  # ConfigError is a ValueError too
        solver_config("default", radius=0)


def test_warnings_of_other_libraries_are_kept(capsys):
    """The CLI prints our warnings as one line each, hands every other
    warning to the hook the process had, and puts that hook back."""
    seen = []

    def hook(message, category, *rest, **kw):
        seen.append((str(message), category))

    def work():
        warnings.warn("a scene note", VoxgiWarning)
        warnings.warn("another library's warning", UserWarning)
        return 0
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = hook
        assert run(work) == 0
        assert warnings.showwarning is hook
    assert capsys.readouterr().err == "warning: a scene note\n"
    assert seen == [("another library's warning", UserWarning)]


@pytest.mark.slow
@pytest.mark.parametrize("args,moments", [
    # voxel solve: import and load, voxelization, photons (20M: several seconds), propagation
    (["--method", "voxels", "--resolution", "128", "--photons", "20000000", "--radius", "16"], [0.5, 2.5, 4.5, 9.0]),
    # the path tracer between and inside bands of rows
    (["--method", "pathtrace", "--spp", "16384", "--width", "64", "--height", "64"], [3.0, 6.0]),
])
def test_ctrl_c_at_any_moment_writes_nothing(tmp_path, args, moments):
    """SIGINT at several moments of a run (inside numba kernels too): one
    line, exit 130, no output and no temporary file left."""
    for t in moments:
        out = tmp_path / f"x{t}.png"
        p = subprocess.Popen([sys.executable, "-m", "baker", "render", "cornell_box", *args, "-o", str(out)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(t)
        p.send_signal(signal.SIGINT)
        stdout, stderr = p.communicate(timeout=120)
        assert p.returncode == 130, (t, stderr[-2000:])
        assert stderr.strip().splitlines()[-1] == "interrupted: nothing was written", (t, stderr[-2000:])
        assert "Traceback" not in stderr and "SystemError" not in stderr, (t, stderr[-2000:])
        assert not list(tmp_path.iterdir()), t


def test_output_cut_short_by_its_reader():
    """`voxbake info walkthrough | head -1`: the reader may leave before the
    command writes. Here it leaves at once: no traceback, SIGPIPE's exit."""
    p = subprocess.Popen([sys.executable, "-m", "baker", "info", "walkthrough"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait() == 141 and "Traceback" not in err and "BrokenPipe" not in err, err
