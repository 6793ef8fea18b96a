"""Bake benchmark: `voxbake bake` on the Cornell box and the walkthrough
scene at each preset, each run in its own process (so peak memory is the
run's own): time and peak memory per stage, texels, maps, pages, dedup
ratio; what the texels' shading cost (points shaded, shadow and gather
rays, rays per second of the texel stage, cut mean); and the error of
each bake as a viewer shows it against the path tracer at the scene's
camera (128x128; the mean ratio, the worst 8x8 block, the relative RMSE
over the lit pixels, the lamp and two rings of pixels around it
excluded); on the walkthrough also over a crop at full resolution where
the detail is: the sun patch's corner on the floor, seen from 1.2 m above
at 512x512 (about 2 mm a pixel, 256 spp; the mean ratio, the worst 8x8 block and
the RMSE of 4x4-pixel means, which keeps the reference's own noise
out). References are cached in bench/out.

    python bench/bake.py [--runs 3] [--scenes cornell_box walkthrough] [--texel-density D] [--uv U] [--no-probes] [--json]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

from common import ROOT, emit

PRESETS = ("preview", "default", "high")
STAGES = ("bvh", "voxelize", "photons", "propagation", "probes", "charts", "lights", "texels", "atlas", "write")


def bake(scene, preset, out, stats, extra=()):
    r = subprocess.run([sys.executable, "-m", "baker", "bake", scene, "--preset", preset, "-o", out, "--stats",
                        stats, *extra], capture_output=True, text=True, cwd=ROOT)
    if r.returncode:
        raise SystemExit(f"bake {scene} {preset} failed:\n{r.stderr}")
    with open(stats) as f:
        return json.load(f)


def rng(values, fmt="{:.2f}"):
    lo, hi = min(values), max(values)
    return fmt.format(lo) if fmt.format(lo) == fmt.format(hi) else f"{fmt.format(lo)}-{fmt.format(hi)}"


def image_error(scene, path, reference, size):
    """(mean ratio, worst 8x8 block, relative RMSE) of the bake at `path`
    as the viewer shows it at its scene's camera against `reference`,
    over the pixels that do not see a lamp (nor lie within two pixels of
    one)."""
    import baker
    from baker.bake import read_bake, render_bake
    from baker.render.compare import LUMINANCE, compare, lamp_pixels, lit_pixels
    from baker.scene import build_scene_bvh, camera_for, pack
    sc = baker.load_scene(scene)
    bvh = build_scene_bvh(sc)
    lamp = lamp_pixels(bvh, pack(sc), camera_for(sc, None, bvh), size, size)
    img = render_bake(read_bake(path), 0, size, size)
    c = compare(img, reference, lamp=lamp)
    img, ref = img @ LUMINANCE, reference @ LUMINANCE
    lit = lit_pixels(ref, 2, lamp)   # the lamp's outline pixels mix lamp and ceiling: two rings left out
    worst = c.blocks[np.argmax(np.abs(c.blocks - 1))] if len(c.blocks) else 1.0
    return c.mean, worst, float(np.sqrt(np.mean((img[lit] - ref[lit]) ** 2)) / ref[lit].mean())


def reference(scene, spp, size=128):
    """The path tracer's image of a built-in scene at its camera, cached."""
    cache = os.path.join(ROOT, "bench", "out", f"{scene}_pt_{spp}.npy" if scene != "cornell_box" else
                         f"cornell_pt_{spp}.npy")
    if os.path.exists(cache):
        return np.load(cache)
    import baker
    ref = baker.render(baker.load_scene(scene), 0, size, size, spp=spp)
    os.makedirs(os.path.dirname(cache), exist_ok=True)
    np.save(cache, ref)
    return ref


CROP_SPP = 256


def crop_camera(scene):
    """A camera 1.2 m above the walkthrough's floor looking straight down
    at the sun patch's far corner (x 5.51, z 2.55), where its slanted and
    its straight edge meet: 1.1 m of floor across, x up the image."""
    from baker.scene import make_camera
    return make_camera("sun crop", [5.1, 1.2, 2.2], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0], 2 * np.arctan(0.55 / 1.2),
                       1.0)


def crop_error(scene, path, spp=CROP_SPP, size=512):
    """(mean ratio, worst 8x8 block, RMSE of 4x4 means) of the bake at
    `path` against the path tracer over crop_camera's view (cached)."""
    import baker
    from baker.bake import read_bake, render_bake
    from baker.render.compare import LUMINANCE, compare
    cam = crop_camera(scene)
    cache = os.path.join(ROOT, "bench", "out", f"{scene}_sun_crop_pt_{spp}_{size}.npy")
    if os.path.exists(cache):
        ref = np.load(cache)
    else:
        ref = baker.render(baker.load_scene(scene), cam, size, size, spp=spp)
        os.makedirs(os.path.dirname(cache), exist_ok=True)
        np.save(cache, ref)
    img = render_bake(read_bake(path), cam, size, size)
    c = compare(img, ref)
    a = (img @ LUMINANCE).reshape(size // 4, 4, size // 4, 4).mean(axis=(1, 3))
    r = (ref @ LUMINANCE).reshape(size // 4, 4, size // 4, 4).mean(axis=(1, 3))
    worst = c.blocks[np.argmax(np.abs(c.blocks - 1))] if len(c.blocks) else 1.0
    return c.mean, worst, float(np.sqrt(np.mean((a - r) ** 2)) / r.mean()), img, ref


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--scenes", nargs="+", default=["cornell_box", "walkthrough"])
    ap.add_argument("--presets", nargs="+", default=list(PRESETS))
    ap.add_argument("--ref-spp", type=int, default=4096, help="path tracer samples of the references")
    ap.add_argument("--texel-density", type=float, help="passed to every bake (default: the presets')")
    ap.add_argument("--uv", choices=("auto", "per-triangle", "xatlas"), help="passed to every bake (default: the presets')")
    ap.add_argument("--no-probes", action="store_true", help="passed to every bake: no probe stage")
    ap.add_argument("--images", help="write the walkthrough's sun crops (bake and path tracer) as PNGs here")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    extra = ["--texel-density", str(args.texel_density)] if args.texel_density else []
    extra += ["--uv", args.uv] if args.uv else []
    extra += ["--no-probes"] if args.no_probes else []
    rows, shading_rows, error_rows, crop_rows = [], [], [], []
    tmp = tempfile.mkdtemp(prefix="voxgi-bench-")
    for scene in args.scenes:
        for preset in args.presets:
            runs = []
            for k in range(args.runs):
                out, st = os.path.join(tmp, f"{scene}_{preset}.glb"), os.path.join(tmp, f"{scene}_{preset}.json")
                runs.append(bake(scene, preset, out, st, extra))
            c = runs[-1]["counters"]
            stage = {s: rng([r["stages"].get(s, {}).get("seconds", 0.0) for r in runs]) for s in STAGES}
            shaded = f"{c['points_shaded']:,}" if "points_shaded" in c else "-"
            rows.append([scene, preset, f"{c['voxels']:,}", f"{c['texels']:,}", shaded,
                         f"{c['unique']:,}/{c['maps']:,}",
                         c["pages"], f"{c['dedup_ratio']:.2f}", *stage.values(),
                         rng([r["total_seconds"] for r in runs]), rng([r["peak_rss_mb"] for r in runs], "{:.0f}")])
            if "shadow_rays" in c:
                rays = c["shadow_rays"] + c.get("gather_rays", 0)
                per_s = [rays / max(r["stages"]["texels"]["seconds"], 1e-9) / 1e6 for r in runs]
                shading_rows.append([scene, preset, f"{1 / c.get('texel_size_asked', c['cell_size']):.3g}",
                                     f"{c['texels_covered']:,}", shaded, f"{c['shadow_rays']:,}",
                                     f"{c.get('gather_rays', 0):,}", rng(per_s), f"{c['cut_mean']:.0f}"])
            mean, worst, err = image_error(scene, out, reference(scene, args.ref_spp), 128)
            error_rows.append([scene, preset, rng([r["total_seconds"] for r in runs]), f"{mean:.3f}", f"{worst:.2f}",
                               f"{100 * err:.2f}%"])
            if scene == "walkthrough":
                mean, worst, err, img, ref = crop_error(scene, out)
                crop_rows.append([scene, preset, f"{c.get('texel_size_asked', c['cell_size']):.4g}", f"{mean:.3f}",
                                  f"{worst:.2f}", f"{100 * err:.2f}%"])
                if args.images:
                    from PIL import Image
                    os.makedirs(args.images, exist_ok=True)
                    for name, im in ((f"sun_crop_{preset}", img), ("sun_crop_pathtrace", ref)):
                        tone = np.clip(im / (1 + im), 0, 1) ** (1 / 2.2)
                        Image.fromarray((tone * 255).astype(np.uint8)).save(os.path.join(args.images, name + ".png"))
    emit(args, "voxbake bake: stages (seconds, min-max over runs), counts, peak memory", rows,
         ["scene", "preset", "voxels", "texels", "points shaded", "maps stored/all", "pages", "dedup", *STAGES, "total s",
          "peak MiB"])
    if shading_rows:
        emit(args, "texel shading: texels per scene unit, texels with a point, points shaded, rays, million rays "
                   "per second of the texel stage (shadow and gather), cut mean", shading_rows,
             ["scene", "preset", "texels/unit", "texels sampled", "points shaded", "shadow rays", "gather rays",
              "Mrays/s", "cut mean"])
    emit(args, f"bake as the viewer shows it vs the path tracer ({args.ref_spp} spp, 128x128; relative RMSE over "
               "the lit pixels, lamp excluded)", error_rows,
         ["scene", "preset", "bake s", "mean ratio", "worst 8x8 block", "rel. RMSE"])
    if crop_rows:
        emit(args, f"the walkthrough's sun patch at full resolution vs the path tracer ({CROP_SPP} spp, 512x512 "
                   "over 1.1 m of floor; RMSE of 4x4-pixel means)", crop_rows,
             ["scene", "preset", "texel size", "mean ratio", "worst 8x8 block", "rel. RMSE (4x4)"])


if __name__ == "__main__":
    main()
