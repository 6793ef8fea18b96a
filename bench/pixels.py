"""Every pixel in a furnace: closed scenes of one albedo (0.55) and one
emitted radiance (0.9), whose exact radiance is 2.0 everywhere, seen from
inside at --size x --size pixels (default 48): the box, the sphere and the
box with a floating and a resting box (scenes/generate.py). Per scene and
preset: the per-pixel range of the rendered radiance over exact and the
share of pixels within 3%, for

- the lightcuts frame with the voxels as VPLs in its cuts (gather 0) and
  with the preset's final gather (LightcutsConfig.gather), and its time;
- the voxel view;
- the bake's lightmaps as a viewer shows them (--no-bake: left out).

Then the Cornell box's lightcuts frame at --cornell x --cornell (default
128): its time with gather 0 and with the gather, over --runs runs.

    python bench/pixels.py [--size 48] [--presets preview,default] [--high] [--no-bake] [--runs 2] [--json]

`high` solves take minutes here (100,000 cells, 128 photons each): --high
adds it.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings

import numpy as np

from common import emit
from baker import bake_config, lightcuts_config, render, solve, solver_config  # noqa: E402
from baker.errors import VoxgiWarning  # noqa: E402
from baker.scene import build_scene_bvh, camera_for, load_scene, pack  # noqa: E402
from scenes.generate import furnace_box, furnace_obstacles, furnace_sphere  # noqa: E402

ALBEDO, L_E = 0.55, 0.9
EXACT = L_E / (1 - ALBEDO)


def span(img):
    r = img.mean(axis=2).astype(np.float64) / EXACT
    return f"{r.min():.3f}-{r.max():.3f}", f"{100 * np.mean(np.abs(r - 1) < 0.03):.1f}%"


def timed(fn, runs):
    ts, out = [], None
    for _ in range(runs):
        t = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t)
    return out, f"{min(ts):.2f}-{max(ts):.2f}" if runs > 1 else f"{ts[0]:.2f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--presets", default="preview,default")
    ap.add_argument("--high", action="store_true", help="the high preset too (minutes per solve)")
    ap.add_argument("--no-bake", action="store_true")
    ap.add_argument("--cornell", type=int, default=128, help="the Cornell box frame's size (0: skip)")
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    from baker.bake import bake_scene
    presets = args.presets.split(",") + (["high"] if args.high else [])
    rows = []
    s = args.size
    with tempfile.TemporaryDirectory() as tmp:
        for name, build in (("box", furnace_box), ("sphere", furnace_sphere), ("obstacles", furnace_obstacles)):
            path = os.path.join(tmp, name + ".glb")
            build(ALBEDO, np.pi * L_E).save(path)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", VoxgiWarning)
                scene = load_scene(path)
            bvh, surf = build_scene_bvh(scene), pack(scene)
            cam = camera_for(scene, None, bvh)
            for preset in presets:
                t = time.perf_counter()
                sol = solve(scene, solver_config(preset), bvh=bvh, surfaces=surf)
                t_solve = time.perf_counter() - t
                row = [name, preset, f"{t_solve:.1f}"]
                for gather in (0, None):
                    lc = lightcuts_config(preset, **({} if gather is None else {"gather": gather}))
                    img, tf = timed(lambda: render(scene, cam, s, s, "lightcuts", solution=sol, lightcuts=lc, bvh=bvh,
                                                   surfaces=surf), args.runs)
                    row += [*span(img), tf]
                row += [*span(render(scene, cam, s, s, "voxels", solution=sol, bvh=bvh, surfaces=surf))]
                if args.no_bake:
                    row += ["-", "-", "-"]
                else:
                    t = time.perf_counter()
                    result = bake_scene(scene, bake_config(preset))
                    t_bake = time.perf_counter() - t
                    row += [*span(render(result.bake, cam, s, s, "lightmap")), f"{t_bake:.1f}"]
                rows.append(row)
                print(" | ".join(str(c) for c in row), flush=True)
    emit(args, f"Furnaces (albedo {ALBEDO}, L_e {L_E}, exact {EXACT:g}), {s}x{s} from inside: per-pixel ratio to "
               "exact", rows,
         ["scene", "preset", "solve s", "frame (VPLs)", "within 3%", "s", "frame (gather)", "within 3%", "s",
          "voxel view", "within 3%", "bake", "within 3%", "bake s"])
    if args.cornell:
        scene = load_scene("cornell_box")
        bvh, surf = build_scene_bvh(scene), pack(scene)
        cam = camera_for(scene, None, bvh)
        c = args.cornell
        crow = []
        for preset in presets:
            sol = solve(scene, solver_config(preset), bvh=bvh, surfaces=surf)
            row = [preset]
            for gather in (0, None):
                lc = lightcuts_config(preset, **({} if gather is None else {"gather": gather}))
                _, tf = timed(lambda: render(scene, cam, c, c, "lightcuts", solution=sol, lightcuts=lc, bvh=bvh,
                                             surfaces=surf), args.runs)
                row.append(tf)
            crow.append(row)
        emit(args, f"Cornell box lightcuts frame, {c}x{c}, s ({args.runs} runs)", crow,
             ["preset", "gather 0 (the voxels' VPLs)", "the preset's gather"])


if __name__ == "__main__":
    main()
