"""Irradiance probes: count, time and bytes per scene and preset, and the
viewer's frame time with a sphere lit by them.

    python bench/probes.py [--scenes cornell_box,walkthrough] [--presets preview,default] [--window] [--json]

Per scene and preset: the solve (as the bake does it), then the probe
stage alone (bake_probes, timed twice, the faster kept), the grid, the
share of valid probes and the bytes the probe block adds to the bake
file. With --window: voxview's window under Xvfb (llvmpipe) at 1280x720
on the scene's default bake, 90 frames with and without a dropped sphere
(the frame rate the window prints, after a warm-up of its first frames).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

from common import emit


def probe_rows(scenes, presets):
    from baker.presets import bake_config
    from baker.probes import bake_probes, grid_for
    from baker.scene import load_scene, prepare
    from baker.solve import solve
    rows = []
    for name in scenes:
        scene = load_scene(name)
        prepared = prepare(scene)
        for preset in presets:
            cfg = bake_config(preset)
            t0 = time.perf_counter()
            solution = solve(prepared, cfg.solver)
            t_solve = time.perf_counter() - t0
            lo, hi = scene.bounds()
            grid = grid_for(lo, hi, cfg.probes.spacing, cfg.probes.budget)
            times = []
            for _ in range(2):
                t0 = time.perf_counter()
                probes = bake_probes(prepared, solution, grid, cfg.probes.copies, cfg.solver.seed)
                times.append(time.perf_counter() - t0)
            # the block's bytes as the file stores them: float32 SH and distances, float16 irradiance, uint8 validity
            size = probes.sh.nbytes + probes.irradiance.size * 2 + probes.depth.nbytes + probes.valid.size
            rows.append([name, preset, f"{probes.count:,}", " x ".join(str(int(d)) for d in probes.dims),
                         f"{probes.spacing:.3g}", f"{probes.valid.mean():.0%}", probes.rays, f"{t_solve:.1f}",
                         f"{min(times):.2f}", f"{size / 2 ** 20:.2f}"])
            del solution, probes
    return rows


def window_rows(scenes):
    rows = []
    if not shutil.which("xvfb-run"):
        return [["-", "Xvfb not installed", "-", "-"]]
    with tempfile.TemporaryDirectory() as d:
        for name in scenes:
            bake = os.path.join(d, f"{name}.glb")
            subprocess.run([sys.executable, "-m", "baker", "bake", name, "-o", bake], check=True,
                           capture_output=True)
            for label, script in (("no object", []), ("sphere", [{"frame": 1, "key": "O"}])):
                path = os.path.join(d, "s.json")
                with open(path, "w") as f:
                    json.dump(script, f)
                r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x720x24", sys.executable, "-m", "viewer",
                                    bake, "--script", path, "--frames", "90", "--width", "1280", "--height", "720"],
                                   capture_output=True, text=True, timeout=900)
                last = [line for line in r.stdout.splitlines() if "frames in" in line]
                rows.append([name, label, last[-1] if last else r.stderr.strip().splitlines()[-1:]])
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="cornell_box,walkthrough")
    ap.add_argument("--presets", default="preview,default,high")
    ap.add_argument("--window", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    scenes = args.scenes.split(",")
    emit(args, "irradiance probes per scene and preset (probe stage alone, best of 2)",
         probe_rows(scenes, args.presets.split(",")),
         ["scene", "preset", "probes", "grid", "spacing", "valid", "rays", "solve s", "probes s", "MiB in file"])
    if args.window:
        emit(args, "voxview window at 1280x720 under Xvfb (llvmpipe), 90 frames", window_rows(scenes),
             ["scene", "object", "window"])


if __name__ == "__main__":
    main()
