"""The voxel solution on real-world meshes against the path tracer: the
voxel view, the lightcuts frame (the voxels' VPLs in its cuts, gather 0,
and the preset's final gather) and the bake's lightmaps (--no-bake: left
out) at a preset (default: `default`) against the path tracer at
--spp samples per pixel (default 4096), --res x --res pixels (default 128),
the scene's camera, luminance. The lamp's pixels (any of whose 4x4
sub-pixel rays meets an emitter) are left out: the lamp is a hundred
times brighter than the walls, a partly covered pixel would weigh on the
mean more than a wall. Per scene: voxels, the mean ratio, the range of 8x8
block ratios, the share of blocks within 5%, and the lit pixels that come
out black (where the path tracer is over a quarter of the median).

Scenes: scan_room, the public Cornell box OBJ (two-sided as OBJ reads,
and --one-sided) and the public Stanford bunny in a closed room (both from
../shared, skipped where absent), the built-in Cornell box, any files given
on the command line (a scanned model in a room of your own), then the
reproduction cases (scenes.generate.reproduction_case: each failure on a
small scene of its own; --no-cases leaves them out).

    python bench/real_meshes.py [--spp N] [--res N] [--preset P] [--no-cases] [--no-bake] [--json] [FILE ...]

The path-traced references take minutes at 4096 spp (about 0.5-1 M
samples/s on two cores); --spp 512 gives the same picture, noisier.
"""
from __future__ import annotations

import argparse
import os
import time
import warnings

from common import ROOT, emit
from baker.scene import camera_for  # noqa: E402
from baker import load_scene, render, solve, solver_config
from baker.errors import VoxgiWarning
from baker.render.compare import compare, lamp_pixels
from baker.scene import build_scene_bvh, pack

def _blocks(c):
    return [f"{c.blocks.min():.2f}-{c.blocks.max():.2f}", f"{100 * c.within(0.05):.0f}%"]


def measure(scene, res, spp, preset, bake=True):
    """One scene's row: the voxel view, the lightcuts frame with the
    voxels' VPLs in its cuts (gather 0, as before #38) and with the
    preset's final gather, and the bake's lightmaps, each against the
    path tracer."""
    from baker import bake_config, lightcuts_config
    from baker.bake import bake_scene
    bvh, surf = build_scene_bvh(scene), pack(scene)
    cam = camera_for(scene, None, bvh)
    t = time.perf_counter()
    pt = render(scene, cam, res, res, "pathtrace", spp=spp, seed=7, bvh=bvh, surfaces=surf)
    t_pt = time.perf_counter() - t
    lamp = lamp_pixels(bvh, surf, cam, res, res)
    t = time.perf_counter()
    sol = solve(scene, solver_config(preset), bvh=bvh, surfaces=surf)
    t_solve = time.perf_counter() - t
    img = render(scene, cam, res, res, "voxels", solution=sol, bvh=bvh, surfaces=surf)
    c = compare(img, pt, lamp=lamp)
    row = [len(sol.voxels), f"{c.mean:.3f}", *_blocks(c), c.black]
    for gather in (0, None):
        lc = lightcuts_config(preset, **({} if gather is None else {"gather": gather}))
        t = time.perf_counter()
        img = render(scene, cam, res, res, "lightcuts", solution=sol, lightcuts=lc, bvh=bvh, surfaces=surf)
        row += [*_blocks(compare(img, pt, lamp=lamp)), f"{time.perf_counter() - t:.1f}"]
    if bake:
        t = time.perf_counter()
        result = bake_scene(scene, bake_config(preset))
        t_bake = time.perf_counter() - t
        img = render(result.bake, cam, res, res, "lightmap")
        row += [*_blocks(compare(img, pt, lamp=lamp)), f"{t_bake:.1f}"]
    else:
        row += ["-", "-", "-"]
    return row + [f"{t_solve:.1f}", f"{t_pt:.0f}"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="*", help="more scenes to compare (their first camera, or an automatic one)")
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--preset", default="default")
    ap.add_argument("--no-cases", action="store_true", help="leave out the reproduction cases")
    ap.add_argument("--no-bake", action="store_true", help="leave out the bakes")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    mcguire = os.path.join(ROOT, "..", "shared", "realscenes", "mcguire_cornellbox", "CornellBox-Original.obj")
    scenes = [("scan_room", os.path.join(ROOT, "scenes", "scan_room.glb"), False)]
    if os.path.exists(mcguire):  # a public file (CC BY 3.0): read from ../shared, never committed
        scenes += [("CornellBox-Original (two-sided)", mcguire, False),
                   ("CornellBox-Original --one-sided", mcguire, True)]
    else:
        print(f"(McGuire's Cornell box left out: {mcguire} is absent)")
    bunny = os.path.join(ROOT, "..", "shared", "realscenes", "glb", "bunny_room.glb")
    if os.path.exists(bunny):  # the public Stanford bunny in a closed room, from ../shared
        scenes += [("bunny_room", bunny, False)]
    scenes += [("cornell_box", os.path.join(ROOT, "scenes", "cornell_box.glb"), False)]
    scenes += [(os.path.basename(f), f, False) for f in args.files]
    rows = []
    for name, path, one in scenes:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", VoxgiWarning)
            scene = load_scene(path, one_sided=one)
        rows.append([name, *measure(scene, args.res, args.spp, args.preset, not args.no_bake)])
    if not args.no_cases:
        import tempfile
        from scenes.generate import REPRODUCTION_CASES, reproduction_case
        with tempfile.TemporaryDirectory() as tmp:
            for name in REPRODUCTION_CASES:
                path = os.path.join(tmp, name + ".glb")
                reproduction_case(name).save(path)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", VoxgiWarning)  # the duplicates and overlaps they repair
                    scene = load_scene(path)
                rows.append([f"case: {name}", *measure(scene, args.res, args.spp, args.preset, not args.no_bake)])
    emit(args, f"The voxel view, the lightcuts frame and the bake ({args.preset}) against the path tracer ({args.spp} "
               f"spp, {args.res}x{args.res})", rows,
         ["scene", "voxels", "view mean", "view 8x8 blocks", "view within 5%", "black lit pixels",
          "frame (VPLs) blocks", "within 5%", "s", "frame (gather) blocks", "within 5%", "s",
          "bake blocks", "within 5%", "bake s", "solve s", "path tracer s"])


if __name__ == "__main__":
    main()
