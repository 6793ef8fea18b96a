"""The command line as a user meets it: refusals before any work, one-line
errors, what each command prints and writes, Ctrl-C at any moment,
warnings. Commands run in this process (conftest.cli) unless a signal, a
time bound or another working folder is what the test is about."""
import json
import os
import re
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

from baker.bake import read_bake
from baker.errors import ConfigError, VoxgiWarning
from baker.presets import PRESETS, solver_config
from baker.render import METHODS
from baker.startup import run

from .conftest import cli

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CORNELL = os.path.join(ROOT, "scenes", "cornell_box.glb")


def voxbake(*args, cwd=None, timeout=300):
    return subprocess.run([sys.executable, "-m", "baker", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)


def refused(code, err, message):
    assert code == 2 and message in err and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1, err


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
        (["--camera", "nope"], "no camera named 'nope'"),
        (["--spp", "0"], "argument --spp: must lie in 1..1,048,576, got 0"),
        (["--method", "voxels", "--radius", "0"], "argument --radius: must lie in 1..64"),
        (["--width", "0"], "argument --width: must lie in 1..16,384"),
        (["--look-from", "1,2"], "X,Y,Z"),
        (["--method", "nope"], "invalid choice"),
        (["--path-bounces", "-1"], "argument --path-bounces: must lie in 0..999"),
        (["--method", "voxels", "--path-bounces", "1"], "--path-bounces applies to --method pathtrace"),
    ]
    for extra, message in cases:
        refused(*cli("render", CORNELL, "-o", out, *extra)[::2], message)
        assert not out.exists()
    refused(*cli("render", CORNELL, "-o", tmp_path / "no" / "x.png")[::2], "output folder does not exist")
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_bake_refuses_bad_settings(tmp_path):
    cases = [(["-o", tmp_path / "x.png"], "unsupported output format"),
             (["-o", tmp_path / "x.glb", "--texel-density", "-2"],
              "argument --texel-density: must be a finite number above 0"),
             (["-o", tmp_path / "x.glb", "--uv", "atlas"], "invalid choice"),
             (["-o", tmp_path / "x.glb", "--texel-samples", "0"], "argument --texel-samples: must lie in 1..8"),
             (["-o", tmp_path / "x.glb", "--texel-samples", "9"], "argument --texel-samples: must lie in 1..8"),
             (["-o", tmp_path / "x.glb", "--texel-indirect-stride", "0"],
              "argument --texel-indirect-stride: must lie in 1..16"),
             (["-o", tmp_path / "x.glb", "--texel-indirect-stride", "nan"], "argument --texel-indirect-stride"),
             (["-o", tmp_path / "x.glb", "--texel-gather", "-1"], "argument --texel-gather: must lie in 0..65,536"),
             (["-o", tmp_path / "x.glb", "--texel-gather", "1e9"], "argument --texel-gather"),
             (["-o", tmp_path / "x.glb", "--texel-gather-spacing", "-1"], "argument --texel-gather-spacing"),
             (["-o", tmp_path / "x.glb", "--texel-gather-spacing", "nan"], "argument --texel-gather-spacing"),
             (["-o", tmp_path / "x.glb", "--texel-gather-spacing", "17"], "argument --texel-gather-spacing"),
             (["-o", tmp_path / "x.glb", "--gather-rays", "-1"], "argument --gather-rays: must lie in 0..65,536"),
             (["-o", tmp_path / "x.glb", "--gather-rays", "nan"], "argument --gather-rays"),
             # 32 maps of 512 x 512 (every triangle's map at its cap): 1.25 GiB, over a budget of 500 MiB
             (["-o", tmp_path / "x.glb", "--texel-density", "1e6", "--memory-budget", "500"],
              "--texel-density 1e+06 (1e-06 scene units a texel) asks for about 8,388,608 texels (32 pages of "
              "512x512), about 1,280 MiB to bake, over the memory budget (--memory-budget) of 500 MiB"),
             (["-o", tmp_path / "x.glb", "--texel-density", "1e5", "--uv", "xatlas"], "over the memory budget")]
    for args, message in cases:
        refused(*cli("bake", "cornell_box", *args)[::2], message)
    assert os.listdir(tmp_path) == []


def test_info_and_help(tmp_path):
    code, out, _ = cli("info", CORNELL)
    assert code == 0 and "triangles  32" in out and "published" in out and "total emitted power" in out
    code, _, err = cli("info", tmp_path / "nope.obj")
    assert code == 2 and err.strip() == f"error: {tmp_path / 'nope.obj'}: file not found"
    for cmd in ([], ["info"], ["render"], ["bake"], ["audit"]):
        code, out, _ = cli(*cmd, "--help")
        assert code == 0 and "usage: voxbake" in out


def test_help_is_generated_from_the_presets_and_the_methods():
    """--help lists every preset with its values and every render method
    with its description, from the tables themselves."""
    _, bake_help, _ = cli("bake", "--help")
    _, render_help, _ = cli("render", "--help")
    for p in PRESETS.values():
        for text in (bake_help, render_help):
            assert f"  {p.name:<8} {p.about}" in text
            assert f"surface cells {p.solver.surface_cells:,}" in text
            assert f"direct VPLs {p.lightcuts.direct_vpls:,}" in text
    flat = " ".join(bake_help.split())
    assert "(preset: " + "/".join(str(p.solver.surface_cells) for p in PRESETS.values()) + ")" in flat
    assert "(preset: " + "/".join(str(p.texel_samples) for p in PRESETS.values()) + ";" in flat
    flat = " ".join(render_help.split())
    for m in METHODS.values():
        assert m.name in render_help and " ".join(m.about.split()[:6]) in flat, m.name


def test_builtin_scenes_by_name_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = cli("info", "cornell_box")
    assert code == 0 and "triangles  32" in out, err
    code, out, _ = cli("scenes")
    assert code == 0 and "cornell_box" in out and "furnace_box" in out


def test_command_line_camera(tmp_path):
    code, _, err = cli("render", "cornell_box", "--look-from", "0.278,0.273,-0.5", "--look-at", "0.278,0.273,0",
                       "--fov", "30", "--spp", "1", "--width", "8", "--height", "8", "-o", tmp_path / "c.png",
                       "--stats", tmp_path / "s.json")
    assert code == 0, err
    assert json.loads((tmp_path / "s.json").read_text())["counters"]["camera"] == "command line"


def test_voxel_view_and_stats(tmp_path):
    from PIL import Image
    out, stats = tmp_path / "v.png", tmp_path / "s.json"
    code, _, err = cli("render", CORNELL, "--method", "voxels", "--preset", "preview", "--resolution", "16",
                       "--width", "48", "--height", "48", "-o", out, "--stats", stats)
    assert code == 0, err
    img = np.asarray(Image.open(out))
    assert img.shape == (48, 48, 3) and img.mean() > 20
    s = json.loads(stats.read_text())
    for key in ("voxels", "directions_per_bounce", "discrete_rays", "photons", "bounces", "stop_reason"):
        assert key in s["counters"], key
    for stage in ("voxelize", "photons", "propagation", "voxel_view"):
        st = s["stages"][stage]
        assert st["seconds"] >= 0 and st["peak_rss_mb"] > 0
        # the process's CPU time over the stage: every thread's, so at most the wall time on each core
        assert 0 <= st["cpu_seconds"] <= st["seconds"] * (os.cpu_count() or 1) + 0.05, (stage, st)
    assert sum(st["cpu_seconds"] for st in s["stages"].values()) > 0
    code, _, err = cli("render", "scenes/cornell_box.glb", "--method", "voxels", "--resolution", "4000",
                       "--memory-budget", "50", "-o", tmp_path / "x.png")
    assert code == 2 and err.startswith("error: scenes/cornell_box.glb: voxelization"), err
    assert not (tmp_path / "x.png").exists()


def test_bake_writes_a_readable_file_and_a_summary(tmp_path):
    out, stats = tmp_path / "c.glb", tmp_path / "s.json"
    code, stdout, err = cli("bake", "cornell_box", "-o", out, "--preset", "preview", "--resolution", "12",
                            "--photons", "20000", "--stats", stats)
    assert code == 0, err
    for word in ("voxels", "gather rays per bounce", "photons", "texels", "points shaded", "maps stored", "pages",
                 "dedup ratio", "seconds", "peak MiB", "wrote"):
        assert word in stdout
    bake = read_bake(out)
    s = json.load(open(stats))
    assert s["counters"]["pages"] == len(bake.pages) and "texels" in s["stages"]
    # the texel size asked for: one per voxel cell unless --texel-density says otherwise
    cell = s["counters"]["cell_size"]
    row = [line.split(None, 2)[2] for line in stdout.splitlines() if line.strip().startswith("texel size")]
    assert s["counters"]["texel_size_asked"] == cell
    assert row == [f"{cell:.4g} scene units ({1 / cell:.3g} a unit; one voxel cell)"], row   # preview's own layout
    assert sorted(os.listdir(tmp_path)) == ["c.glb", "s.json"]  # nothing else left behind
    code, stdout, err = cli("bake", "cornell_box", "-o", tmp_path / "d.glb", "--preset", "preview", "--resolution",
                            "12", "--photons", "20000", "--texel-density", "40")
    assert code == 0, err
    row = [line.split(None, 2)[2] for line in stdout.splitlines() if line.strip().startswith("texel size")]
    assert row == ["0.025 scene units (40 a unit; as asked)"], row
    code, stdout, err = cli("bake", "cornell_box", "-o", tmp_path / "e.glb", "--preset", "preview", "--resolution",
                            "12", "--photons", "20000", "--uv", "auto")
    assert code == 0, err
    row = [line.split(None, 2)[2] for line in stdout.splitlines() if line.strip().startswith("texel size")]
    auto = r"uv per-triangle \(auto: per-triangle maps would shade [0-9.]+x the points of charts\)\)"
    assert len(row) == 1 and re.fullmatch(re.escape(f"{cell:.4g} scene units ({1 / cell:.3g} a unit; one voxel cell; ")
                                          + auto, row[0]), row


def test_every_render_method_runs_from_the_command_line(tmp_path):
    """Each of METHODS through `voxbake render`, with the stats it records."""
    bake = tmp_path / "b.glb"
    assert cli("bake", "cornell_box", "-o", bake, "--preset", "preview", "--resolution", "12", "--photons",
               "20000", "--preview-vpls", "64")[0] == 0
    extra = {"pathtrace": ["--spp", "2"], "instant-radiosity": ["--frames", "2"], "lightmap": []}
    expect = {"pathtrace": "spp", "voxels": "discrete_rays", "lightcuts": "cut_mean", "instant-radiosity": "ir_frames",
              "lightmap": "camera"}
    for name, method in METHODS.items():
        scene = bake if method.bake else "cornell_box"
        out, stats = tmp_path / f"{name}.exr", tmp_path / f"{name}.json"
        code, _, err = cli("render", scene, "--method", name, "--preset", "preview", "--resolution", "12",
                           "--photons", "20000", "--direct-vpls", "64", "--width", "8", "--height", "8", "-o", out,
                           "--stats", stats, *extra.get(name, []))
        assert code == 0, (name, err)
        assert expect[name] in json.loads(stats.read_text())["counters"], name


def test_frame_gather_flags_reach_the_frame(tmp_path):
    """--frame-gather sets the lightcuts frame's gather rays (0: the voxels
    as VPLs in the cuts); the stats and the summary say which; an
    out-of-range value is refused in one line."""
    seen = {}
    for rays in ("0", "32"):
        stats = tmp_path / f"g{rays}.json"
        code, out, err = cli("render", "cornell_box", "--method", "lightcuts", "--preset", "preview", "--resolution",
                             "12", "--photons", "20000", "--direct-vpls", "64", "--width", "8", "--height", "8",
                             "--frame-gather", rays, "--frame-gather-spacing", "0", "-o", tmp_path / f"g{rays}.exr",
                             "--stats", stats)
        assert code == 0, err
        seen[rays] = json.loads(stats.read_text())["counters"]["gather"]
    assert seen == {"0": 0, "32": 32}
    code, _, err = cli("render", "cornell_box", "--method", "lightcuts", "--frame-gather", "-1", "-o",
                       tmp_path / "x.exr")
    assert code != 0 and "--frame-gather" in err and len(err.strip().splitlines()) <= 3


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


def test_a_texel_density_beyond_memory_is_refused_before_any_work(tmp_path):
    """The walkthrough (102k triangles) at 10,000 texels a unit: 2.7e10
    texels. Refused from the layout's own count before the solve starts
    (no stage ran: the stats file is never written), nothing on disk."""
    from baker import load_scene
    from baker.bake import bake_config, bake_scene
    from baker.errors import BudgetError
    rc, out, err = cli("bake", "walkthrough", "-o", tmp_path / "w.glb", "--texel-density", "1e4",
                       "--stats", tmp_path / "s.json")
    assert rc == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    assert "asks for about 26,805,272,576 texels" in err and "lower --texel-density" in err
    assert os.listdir(tmp_path) == []
    with pytest.raises(BudgetError, match="asks for about 8,388,608 texels") as e:
        bake_scene(load_scene("cornell_box"), bake_config("preview", texel_density=1e6, memory_budget_mb=100))
    assert e.value.path.endswith("cornell_box.glb")
