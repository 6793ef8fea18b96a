"""The real architectural scenes (../shared/realscenes/big and any files
given), loaded and baked as a user runs them.

Load table: per scene, the load's wall time, its peak resident memory
(each scene loaded in a fresh process, so the figure is that load's own),
and the triangles in the file and after the clean-up (degenerate and
duplicate triangles dropped, coplanar overlaps cut), with the triangles
cut and those left whole.

Bake table (--bake): per scene and preset (--presets, default preview and
default), `voxbake bake` in a fresh process (the gazebo and the living
room, which have no lamp, under --sky 1,1,1 and --sky 20.3,13.5,8.7, the
living room's cosine-weighted mean of its environment map): the stages' seconds (load,
voxel solve, texels), the whole command's wall time and peak resident
memory, the lightmap pages; then the bake as our viewer shows it (the CPU
view of the bake file, `voxbake render --method lightmap`) against the
path tracer from the scene's camera at --res x --res (default 128) and
--spp (default 1024, two seeds whose difference estimates the
reference's own noise): luminance, the light sources' pixels (lamps, the
sky through windows) left out; the mean ratio, the worst 8x8 block's
ratio, the share of blocks within 10%, and the relative RMSE less the
reference's noise; and the share of blocks in which the reference's two
halves agree within 5% (where that is all of them, a bake's block beyond
10% is its own error, not the reference's noise). References are kept in bench/out/ (keyed by the
file's SHA-256, the light, --res and --spp).

    python bench/real_scenes.py [--runs N] [--bake] [--presets P,Q] [--scenes A,B] [--spp N] [--res N] [--json] [FILE ...]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

from common import ROOT, emit, rel_rmse

BIG = os.path.join(ROOT, "..", "shared", "realscenes", "big")
OUT = os.path.join(ROOT, "bench", "out")
# the light a user gives a scene that has no lamp of its own
LIGHT = {"gazebo.glb": ["--sky", "1,1,1"], "bitterli_living_room.glb": ["--sky", "20.3,13.5,8.7"]}

CHILD = r"""
import json, re, sys, time, warnings
t = time.perf_counter()
from baker.scene import load_scene
t_import = time.perf_counter() - t
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    t = time.perf_counter()
    scene = load_scene(sys.argv[1])
    t_load = time.perf_counter() - t
notes = " ".join(str(w.message) for w in caught)
cut = re.search(r"cut the overlapping part out of (\d+)", notes)
whole = re.search(r"left (\d+) coplanar", notes)
from baker.stats import peak_rss_mb
print(json.dumps({"load_s": t_load, "import_s": t_import, "triangles": int(len(scene.triangles)),
                  "cut": int(cut.group(1)) if cut else 0, "whole": int(whole.group(1)) if whole else 0,
                  "peak_mb": peak_rss_mb()}))
"""

FILE_TRIANGLES = r"""
import sys
from baker.scene.gltf_read import read_gltf
from baker.scene.obj import read_obj
p = sys.argv[1]
parts = read_gltf(p) if p.endswith((".glb", ".gltf")) else read_obj(p)
print(len(parts["triangles"]))
"""


def run_child(code, path):
    """stdout of a fresh interpreter running `code`."""
    return run_command([sys.executable, "-c", code, path], path)


def run_command(argv, what):
    """stdout of a fresh process running argv (its output through files: a
    bake's progress bars would fill a pipe). Its peak memory comes from
    the child itself (baker.stats.peak_rss_mb): the rusage of a child
    started with vfork counts this process's own peak too."""
    import tempfile
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        p = subprocess.Popen(argv, stdout=out, stderr=err, cwd=ROOT)
        p.wait()
        out.seek(0)
        err.seek(0)
        text, problem = out.read().decode(), err.read().decode(errors="replace").strip()
    if p.returncode != 0:
        raise SystemExit(f"{what}: {problem.splitlines()[-1] if problem else f'exit {p.returncode}'}")
    return text


def reference(path, light, res, spp):
    """(image, half difference, seconds) of the path tracer from the
    scene's camera: two half-runs with their own seeds, averaged, and half
    their difference (whose RMS over some pixels is the noise of the mean
    there). Cached in bench/out/."""
    import hashlib

    import numpy as np
    with open(path, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()[:16]
    key = hashlib.sha256(repr((digest, light, res, spp)).encode()).hexdigest()[:16]
    cache = os.path.join(OUT, f"realscene_ref_{os.path.basename(path)}_{key}.npz")
    if os.path.exists(cache):
        z = np.load(cache)
        if "half_diff" in z:
            return z["image"], z["half_diff"], float(z["seconds"])
    import time
    from baker import render
    t = time.perf_counter()
    scene, bvh, surf, cam = open_scene(path, light)
    halves = [render(scene, cam, res, res, "pathtrace", spp=spp // 2, seed=s, bvh=bvh, surfaces=surf)
              for s in (11, 12)]
    seconds = time.perf_counter() - t
    image = (0.5 * (halves[0].astype(np.float64) + halves[1])).astype(np.float32)
    half_diff = (0.5 * (halves[0].astype(np.float64) - halves[1])).astype(np.float32)
    os.makedirs(OUT, exist_ok=True)
    np.savez_compressed(cache, image=image, half_diff=half_diff, seconds=seconds)
    return image, half_diff, seconds


def open_scene(path, light):
    """(scene, bvh, surfaces, the scene's first camera) under `light`
    (voxbake's --sky arguments or [])."""
    import warnings

    import numpy as np
    from baker.errors import VoxgiWarning
    from baker.scene import Sky, build_scene_bvh, camera_for, load_scene, pack
    sky = Sky(np.array([float(v) for v in light[1].split(",")])) if light else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", VoxgiWarning)
        scene = load_scene(path, sky=sky)
    bvh = build_scene_bvh(scene)
    return scene, bvh, pack(scene), camera_for(scene, None, bvh)


def bake_row(path, preset, res, spp, tmp):
    """One row of the bake table."""
    import numpy as np
    from baker.bake import read_bake, render_bake
    from baker.render.compare import compare, lamp_pixels
    light = LIGHT.get(os.path.basename(path), [])
    out, stats = os.path.join(tmp, "bake.glb"), os.path.join(tmp, "stats.json")
    import time
    t = time.perf_counter()
    run_command([sys.executable, "-m", "baker", "bake", path, "-o", out, "--preset", preset, "--stats", stats,
                 *light], f"{path} ({preset})")
    wall = time.perf_counter() - t
    with open(stats) as f:
        st = json.load(f)
    peak = st["peak_rss_mb"]
    sec = {k: v["seconds"] for k, v in st["stages"].items()}
    solve = sum(sec.get(k, 0.0) for k in ("bvh", "voxelize", "photons", "propagation"))
    texels = sum(sec.get(k, 0.0) for k in ("charts", "lights", "texels", "atlas"))
    ref, half_diff, _ = reference(path, light, res, spp)
    scene, bvh, surf, cam = open_scene(path, light)
    img = render_bake(read_bake(out), cam, res, res)
    lamp = lamp_pixels(bvh, surf, cam, res, res)
    c = compare(img, ref, lamp=lamp)
    lum = np.array([0.2126, 0.7152, 0.0722])
    keep = ~lamp & ((ref @ lum) > 0)
    # the reference's noise over the pixels compared (the sky seen through windows is bright and noiseless)
    noise = float(np.sqrt(np.mean((half_diff @ lum)[keep] ** 2)) / (ref @ lum)[keep].mean())
    err = rel_rmse(img[keep][None], ref[keep][None], np.zeros((1, int(keep.sum())), bool), noise)
    worst = c.blocks[np.argmax(np.abs(c.blocks - 1))] if len(c.blocks) else 1.0
    # the reference's two halves against each other: where they agree within 5% in every block, a block of
    # the bake beyond 10% is the bake's own error, not the reference's noise
    halves = compare(ref + half_diff, ref - half_diff, lamp=lamp)
    return [os.path.basename(path), preset, f"{sec.get('load', 0):.1f}", f"{solve:.1f}", f"{texels:.1f}",
            f"{wall:.1f}", f"{peak:.0f}", st["counters"].get("pages", "-"), f"{c.mean:.3f}", f"{worst:.2f}",
            f"{100 * c.within(0.10):.0f}%", f"{100 * err:.1f}", f"{100 * noise:.1f}",
            f"{100 * halves.within(0.05):.0f}%"], img, ref


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="*", help="more scenes to load")
    ap.add_argument("--runs", type=int, default=3, help="loads per scene (the range is reported)")
    ap.add_argument("--bake", action="store_true", help="bake every scene and compare it with the path tracer")
    ap.add_argument("--no-load", action="store_true", help="leave out the load table")
    ap.add_argument("--presets", default="preview,default", help="presets to bake at (comma-separated)")
    ap.add_argument("--spp", type=int, default=1024, help="path tracer samples per pixel (the reference)")
    ap.add_argument("--res", type=int, default=128, help="image side for the comparison")
    ap.add_argument("--images", help="write each bake view and reference as PNG into this folder")
    ap.add_argument("--scenes", help="only these of the real scenes (comma-separated names, e.g. gazebo,bitterli_modern_hall)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    # smallest first: the quick rows come first
    files = sorted((os.path.join(BIG, f) for f in os.listdir(BIG) if f.endswith(".glb")), key=os.path.getsize) \
        if os.path.isdir(BIG) else []
    if args.scenes:
        names = set(args.scenes.split(","))
        files = [f for f in files if os.path.splitext(os.path.basename(f))[0] in names]
    files += args.files
    if not files:
        raise SystemExit(f"no scenes: {BIG} is absent and no file was given")
    if not args.no_load:
        load_table(args, files)
    if args.bake:
        bake_table(args, files)


def bake_table(args, files):
    import tempfile
    rows = []
    for path in files:
        for preset in args.presets.split(","):
            with tempfile.TemporaryDirectory() as tmp:
                row, img, ref = bake_row(path, preset, args.res, args.spp, tmp)
            rows.append(row)
            print(" | ".join(str(c) for c in row), file=sys.stderr)
            if args.images:
                from baker.render import write_image
                os.makedirs(args.images, exist_ok=True)
                stem = os.path.join(args.images, os.path.splitext(os.path.basename(path))[0])
                write_image(f"{stem}_{preset}.png", img)
                write_image(f"{stem}_pathtrace.png", ref)
    emit(args, f"Baking real scenes: voxbake bake per preset, the bake's view against the path tracer ({args.spp} "
               f"spp, {args.res}x{args.res})", rows,
         ["scene", "preset", "load s", "solve s", "texels s", "total s", "peak MiB", "pages", "mean ratio",
          "worst 8x8 block", "blocks within 10%", "rel. RMSE %", "reference noise %",
          "reference halves: blocks within 5%"])


def load_table(args, files):
    rows = []
    for path in files:
        n_file = int(run_child(FILE_TRIANGLES, path))
        loads, peaks, info = [], [], None
        for _ in range(args.runs):
            info = json.loads(run_child(CHILD, path))
            loads.append(info["load_s"])
            peaks.append(info["peak_mb"])
        rows.append([os.path.basename(path), f"{n_file:,}", f"{info['triangles']:,}", f"{info['cut']:,}",
                     f"{info['whole']:,}", f"{min(loads):.2f}-{max(loads):.2f}", f"{max(peaks):.0f}"])
    emit(args, "Loading real scenes (voxbake info's load: parse, validate, clean up)", rows,
         ["scene", "triangles in file", "triangles loaded", "cut", "left whole", "load s", "peak MiB"])


if __name__ == "__main__":
    main()
