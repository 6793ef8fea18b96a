"""Bake benchmark: `voxbake bake` on the Cornell box and the walkthrough
scene at each preset, each run in its own process (so peak memory is the
run's own): time and peak memory per stage, texels, maps, pages, dedup
ratio; and the error of the baked Cornell box as a viewer shows it against
the path tracer (relative RMSE over the lit pixels, lamp excluded).

    python bench/bake.py [--runs 3] [--scenes cornell_box walkthrough] [--json]
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
STAGES = ("bvh", "voxelize", "photons", "propagation", "charts", "lights", "texels", "atlas", "write")


def bake(scene, preset, out, stats):
    r = subprocess.run([sys.executable, "-m", "baker", "bake", scene, "--preset", preset, "-o", out, "--stats",
                        stats], capture_output=True, text=True, cwd=ROOT)
    if r.returncode:
        raise SystemExit(f"bake {scene} {preset} failed:\n{r.stderr}")
    with open(stats) as f:
        return json.load(f)


def rng(values, fmt="{:.2f}"):
    lo, hi = min(values), max(values)
    return fmt.format(lo) if fmt.format(lo) == fmt.format(hi) else f"{fmt.format(lo)}-{fmt.format(hi)}"


def image_error(path, reference, size):
    from baker.bake import read_bake, render_bake
    from baker.render.compare import LUMINANCE, lit_pixels
    img = render_bake(read_bake(path), 0, size, size) @ LUMINANCE
    ref = reference @ LUMINANCE
    lit = lit_pixels(ref)
    return float(np.sqrt(np.mean((img[lit] - ref[lit]) ** 2)) / ref[lit].mean())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--scenes", nargs="+", default=["cornell_box", "walkthrough"])
    ap.add_argument("--presets", nargs="+", default=list(PRESETS))
    ap.add_argument("--ref-spp", type=int, default=4096, help="path tracer samples of the Cornell reference")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows, error_rows = [], []
    ref = None
    tmp = tempfile.mkdtemp(prefix="voxgi-bench-")
    for scene in args.scenes:
        for preset in args.presets:
            runs = []
            for k in range(args.runs):
                out, st = os.path.join(tmp, f"{scene}_{preset}.glb"), os.path.join(tmp, f"{scene}_{preset}.json")
                runs.append(bake(scene, preset, out, st))
            c = runs[-1]["counters"]
            stage = {s: rng([r["stages"].get(s, {}).get("seconds", 0.0) for r in runs]) for s in STAGES}
            shaded = f"{c['points_shaded']:,}" if "points_shaded" in c else "-"
            rows.append([scene, preset, f"{c['voxels']:,}", f"{c['texels']:,}", shaded,
                         f"{c['unique']:,}/{c['maps']:,}",
                         c["pages"], f"{c['dedup_ratio']:.2f}", *stage.values(),
                         rng([r["total_seconds"] for r in runs]), rng([r["peak_rss_mb"] for r in runs], "{:.0f}")])
            if scene == "cornell_box":
                if ref is None:
                    cache = os.path.join(ROOT, "bench", "out", f"cornell_pt_{args.ref_spp}.npy")
                    if os.path.exists(cache):
                        ref = np.load(cache)
                    else:
                        import baker
                        ref = baker.render(baker.load_scene("cornell_box"), 0, 128, 128, spp=args.ref_spp)
                        os.makedirs(os.path.dirname(cache), exist_ok=True)
                        np.save(cache, ref)
                err = image_error(out, ref, 128)
                error_rows.append([preset, rng([r["total_seconds"] for r in runs]), f"{100 * err:.2f}%"])
    emit(args, "voxbake bake: stages (seconds, min-max over runs), counts, peak memory", rows,
         ["scene", "preset", "voxels", "texels", "points shaded", "maps stored/all", "pages", "dedup", *STAGES, "total s",
          "peak MiB"])
    if error_rows:
        emit(args, f"Cornell box bake as the viewer shows it vs the path tracer ({args.ref_spp} spp, 128x128): "
                   "relative RMSE over the lit pixels", error_rows, ["preset", "bake s", "rel. RMSE"])


if __name__ == "__main__":
    main()
