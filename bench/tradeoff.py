"""The speed/accuracy trade, measured (docs/design.md section 11).

For each scene, each preset, and one knob at a time around the presets of
--around (preview and default: around high, a bake takes minutes):
the whole bake (`bake_scene`: voxels, photons, propagation, VPLs and light
tree, texels, atlas), timed per stage, its peak memory, and the error of
what a user sees: the baked lightmaps rendered from the scene's camera
(`render_bake`: albedo x H / pi through the lightmap, box-filtered
subpixels) against a converged path-traced image of the same camera.

Error (luminance, over the pixels that see no lamp): relative RMSE over the
reference's mean there (its own noise subtracted); the 95th percentile and
the maximum of the per-pixel relative error |a - r| / max(r, mean / 20),
also without the two rings of pixels the lamp's edge covers in part; the
worst 8x8 block's mean ratio, as |ratio - 1| (render/compare.py).

Knobs (values relative to the preset they are swept around):
surface_cells (the voxel count: x1/4, x1/2, x2), radius (r -4, -2, +4),
schedule (the other one), photons_per_voxel (x1/4, x1/2, x2, x4),
photon_smoothing (0, 2, 3 standard deviations), tolerance (x10, x0.1),
epsilon (x2.5, x0.5, x0.25) and cap (x0.3, x3) of lightcuts, direct_vpls
(x1/4, x4), texels per cell (0.5, 2). The preview tier takes its texels
from the voxels: lightcuts knobs do not apply to it.

Writes bench/results/tradeoff.csv, tradeoff.md and tradeoff.png (error
against time per scene, the Pareto front, the presets marked). The
path-traced references are cached in bench/out (keyed by scene file hash,
size and spp), so a rerun costs only the bakes.

    python bench/tradeoff.py [--scenes cornell_box,walkthrough,scan_room]
        [--around preview,default] [--size 96] [--ref-spp 4096]
        [--knobs NAME,...] [--seeds 2] [--presets preview,default,high] [--append]
        [--out bench/results]

Each point is baked with --seeds seeds (photons, VPLs, representatives):
one bake's error is partly noise (lightcuts' representatives, photons),
+-0.5-1% at the default preset, as large as what most knobs change; the
table gives the mean and half the spread.
"""
from __future__ import annotations

import argparse
import csv
import math
import os
import time

import numpy as np

from common import ROOT, cached_reference, machine, table
from baker.scene import camera_for  # noqa: E402

LUM = np.array([0.2126, 0.7152, 0.0722])
STAGES = ("bvh", "voxelize", "photons", "propagation", "charts", "lights", "texels", "atlas")


def knob_values(preset):
    """(knob, value, overrides for bake_config) around a preset."""
    from baker.presets import PRESETS
    s, lc = PRESETS[preset].solver, PRESETS[preset].lightcuts
    out = []
    for f in (0.25, 0.5, 2.0):
        out.append(("surface_cells", int(s.surface_cells * f), {"surface_cells": int(s.surface_cells * f)}))
    for d in (-4, -2, 4):
        if s.radius + d >= 2:
            out.append(("radius", s.radius + d, {"radius": s.radius + d}))
    other = "constant" if s.schedule == "halving" else "halving"
    out.append(("schedule", other, {"schedule": other}))
    for f in (0.25, 0.5, 2.0, 4.0):
        out.append(("photons_per_voxel", s.photons_per_voxel * f, {"photons_per_voxel": s.photons_per_voxel * f}))
    for k in (0.0, 2.0, 3.0):
        if k != s.photon_smoothing:
            out.append(("photon_smoothing", k, {"photon_smoothing": k}))
    for f in (10.0, 0.1):
        out.append(("tolerance", s.tolerance * f, {"tolerance": s.tolerance * f}))
    if preset != "preview":
        for f in (2.5, 0.5, 0.25):
            out.append(("epsilon", round(lc.epsilon * f, 5), {"epsilon": round(lc.epsilon * f, 5)}))
        for f in (0.3, 3.0):
            out.append(("cap", int(lc.cap * f), {"cap": int(lc.cap * f)}))
        for f in (0.25, 4.0):
            out.append(("direct_vpls", int(lc.direct_vpls * f), {"direct_vpls": int(lc.direct_vpls * f)}))
    for t in (0.5, 2.0):
        out.append(("texels_per_cell", t, {"texels_per_cell": t}))
    return out


def peak_reset():
    """Reset the process's peak resident memory (Linux clear_refs 5); the
    resident memory now, MiB."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass
    return _status("VmRSS")


def _status(key):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key):
                return int(line.split()[1]) / 1024
    return float("nan")


def errors(img, ref, lamp, ref_noise):
    """(relative RMSE over the pixels that see no lamp, 95th percentile and
    max of the per-pixel relative error without the two rings of pixels
    the lamp's edge covers in part, the worst 8x8 block's |ratio - 1|)."""
    from baker.render.compare import compare, grow
    a, r = np.asarray(img, np.float64) @ LUM, np.asarray(ref, np.float64) @ LUM
    keep = ~lamp
    m = r[keep].mean()
    mse = np.mean((a - r)[keep] ** 2) - (ref_noise * m) ** 2
    ring = grow(lamp, 2)
    rel = np.abs(a - r)[~ring] / np.maximum(r[~ring], m / 20)
    return (math.sqrt(max(mse, 0.0)) / m, float(np.percentile(rel, 95)), float(rel.max()),
            float(compare(img, ref, lamp=lamp, lamp_rings=2).worst))


def bake_point(scene, bvh, surf, cam, size, preset, overrides):
    """One bake at a preset with overrides: (stage seconds, total s, (peak, before) resident MiB, voxels,
    image)."""
    from baker.bake.pipeline import bake_config, bake_scene
    from baker.render.lightmap_view import render_bake
    from baker.presets import solver_config
    from baker.stats import Stats
    o = dict(overrides)
    tpc = o.pop("texels_per_cell", None)
    lc_keys = {k: o.pop(k) for k in ("epsilon", "direct_vpls", "cap") if k in o}
    cap = lc_keys.pop("cap", None)
    density = None
    if tpc is not None:
        from baker.voxels import grid_for, resolution_for
        cfg = solver_config(preset, **o)
        density = tpc / grid_for(scene, resolution_for(scene, cfg), cfg.cell_size).h
    config = bake_config(preset, texel_density=density, **lc_keys, **o)
    if cap is not None:
        from dataclasses import replace
        config = replace(config, lightcuts=replace(config.lightcuts, cap=cap))
    base = peak_reset()
    stats = Stats("bake")
    t = time.perf_counter()
    result = bake_scene(scene, config, stats=stats, bvh=bvh, surfaces=surf)
    bake, solution = result.bake, result.solution
    total = time.perf_counter() - t
    peak = _status("VmHWM")  # the process's peak during the bake (its level before it: `base`)
    img = render_bake(bake, cam, size, size)  # its own BVH: the bake orders its triangles by page
    d = stats.as_dict()
    st = {k: d.get("stages", {}).get(k, {}).get("seconds", 0.0) for k in STAGES}
    return st, total, (peak, base), len(solution.voxels), img


def pareto(points):
    """Indices of the points no other point beats in both time and error."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(1, len(scenes), figsize=(5.2 * len(scenes), 4.4), squeeze=False)
    colours = {"preview": "tab:green", "default": "tab:blue", "high": "tab:red"}
    for ax, sc in zip(axes[0], scenes):
        rs = [r for r in rows if r["scene"] == sc]
        pts = [(r["seconds"], 100 * r["rel_rmse"]) for r in rs]
        seen = set()
        for r, p in zip(rs, pts):
            if r["knob"].startswith("preset"):
                continue
            label = None if r["around"] in seen else f"a knob changed around {r['around']}"
            seen.add(r["around"])
            ax.scatter(*p, s=14, color=colours[r["around"]], alpha=0.5, lw=0, label=label)
        f = pareto(pts)
        ax.plot([pts[i][0] for i in f], [pts[i][1] for i in f], "k-", lw=1, label="Pareto front")
        for r, p in zip(rs, pts):
            if r["knob"] == "preset before retune":
                ax.scatter(*p, s=90, marker="*", facecolor="none", edgecolor=colours[r["around"]], zorder=5,
                           label=f"{r['around']} before the retune")
            if r["knob"] == "preset":
                ax.scatter(*p, s=120, marker="*", color=colours[r["around"]], edgecolor="k", zorder=5,
                           label=f"{r['around']} preset")
                ax.annotate(r["around"], p, textcoords="offset points", xytext=(6, 4), fontsize=8)
        ax.set_xscale("log")
        from matplotlib.ticker import NullFormatter, ScalarFormatter
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_ylim(0, None)
        ax.set_xlabel("bake seconds (2 cores)")
        ax.set_ylabel("relative RMSE of the lit image, %")
        ax.set_title(sc)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("voxgi: bake time against the error of the baked image (96x96, against the path tracer)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="cornell_box,walkthrough,scan_room")
    ap.add_argument("--around", default="preview,default",
                    help="presets to sweep the knobs around (each preset's own point is always measured)")
    ap.add_argument("--knobs", default="", help="only these knobs (comma-separated; default: all)")
    ap.add_argument("--presets", default="preview,default,high", help="the presets whose own points are measured")
    ap.add_argument("--replot", action="store_true", help="no bakes: rewrite the table and plot from tradeoff.csv")
    ap.add_argument("--append", action="store_true",
                    help="keep the rows of an existing tradeoff.csv that this run does not measure again (a "
                         "preset measured again keeps its earlier point as 'preset before retune')")
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--seeds", type=int, default=2, help="bakes per point (seeds 0, 1, ...): errors and times averaged")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    args = ap.parse_args()
    import warnings

    import baker
    from baker.errors import VoxgiWarning
    from baker.render import camera_array
    from baker.scene import build_scene_bvh, pack
    warnings.simplefilter("ignore", VoxgiWarning)
    os.makedirs(args.out, exist_ok=True)
    only = set(filter(None, args.knobs.split(",")))
    rows = []
    s = args.size
    for name in ([] if args.replot else args.scenes.split(",")):
        scene = baker.load_scene(name)
        bvh, surf = build_scene_bvh(scene), pack(scene)
        cam = camera_for(scene, None, bvh)
        ref, lamp, ref_noise, ref_s = cached_reference(name, scene, bvh, surf, camera_array(cam, s, s), s,
                                                       args.ref_spp)
        print(f"{name}: reference {args.ref_spp} spp ({ref_s:.0f} s, noise {100 * ref_noise:.2f}%)", flush=True)
        bake_point(scene, bvh, surf, cam, 8, "preview", {"surface_cells": 500})  # compile / load kernels
        around = set(filter(None, args.around.split(",")))
        measured = set(filter(None, args.presets.split(",")))
        for preset in [p for p in ("preview", "default", "high") if p in measured | around]:
            points = [("preset", "", {})] if preset in measured else []
            if preset in around:
                points += [p for p in knob_values(preset) if not only or p[0] in only]
            for knob, value, over in points:
                runs = []
                for seed in range(args.seeds):  # the error of one bake is partly noise: average over seeds
                    st, total, peak, nvox, img = bake_point(scene, bvh, surf, cam, s, preset, dict(over, seed=seed))
                    runs.append((st, total, peak) + errors(img, ref, lamp, ref_noise))
                st = {k: float(np.mean([r[0][k] for r in runs])) for k in STAGES}
                total = float(np.mean([r[1] for r in runs]))
                peak, base = float(max(r[2][0] for r in runs)), float(min(r[2][1] for r in runs))
                es = [r[3] for r in runs]
                e, p95, emax, worst = (float(np.mean([r[i] for r in runs])) for i in (3, 4, 5, 6))
                row = {"scene": name, "around": preset, "knob": knob, "value": value, "voxels": nvox,
                       "seconds": round(total, 3), **{f"s_{k}": round(v, 3) for k, v in st.items()},
                       "peak_mib": round(peak, 1), "before_mib": round(base, 1), "rel_rmse": round(e, 5), "p95": round(p95, 5),
                       "max": round(emax, 4), "worst_block": round(worst, 4),
                       "rmse_spread": round(max(es) - min(es), 5), "seeds": args.seeds}
                rows.append(row)
                print(f"  {preset:8s} {knob:18s} {str(value):>8s}  {nvox:7d} voxels  {total:7.2f} s  "
                      f"{peak:7.0f} MiB peak  rmse {100 * e:6.2f}% ({100 * min(es):.2f}-{100 * max(es):.2f})  p95 {100 * p95:6.1f}%  max {100 * emax:6.0f}%",
                      flush=True)
    path = os.path.join(args.out, "tradeoff.csv")
    if (args.append or args.replot) and os.path.exists(path):
        new = {(r["scene"], r["around"], r["knob"], str(r["value"])) for r in rows}
        with open(path) as f:
            old = [r for r in csv.DictReader(f) if (r["scene"], r["around"], r["knob"], r["value"]) not in new
                   or r["knob"] == "preset"]
        for r in old:  # a preset measured again (after a retune): the earlier point stays, named as such
            if r["knob"] == "preset" and (r["scene"], r["around"], "preset", "") in new:
                r["knob"] = "preset before retune"
        for r in old:
            for k, v in r.items():
                if k not in ("scene", "around", "knob", "value"):
                    r[k] = int(float(v)) if k in ("voxels", "seeds") else float(v)
        rows = old + rows
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = [f"# The speed/accuracy trade ({time.strftime('%Y-%m-%d')})", "", f"machine: {machine()}", "",
             f"Bakes timed in process after a warm-up; error of the bake seen from the scene's camera "
             f"({s}x{s}) against the path tracer at {args.ref_spp} spp. On front: no other point of the "
             f"scene is both faster and more accurate.", ""]
    for name in dict.fromkeys(r["scene"] for r in rows):
        rs = [r for r in rows if r["scene"] == name]
        front = set(pareto([(r["seconds"], r["rel_rmse"]) for r in rs]))
        lines += [f"## {name}", "", table(
            [[r["around"], r["knob"], r["value"], r["voxels"], f"{r['seconds']:.2f}",
              " / ".join(f"{r['s_' + k]:.2f}" for k in ("voxelize", "photons", "propagation", "lights", "texels")),
              f"{r['peak_mib']:.0f} ({r['before_mib']:.0f})", f"{100 * r['rel_rmse']:.2f} (±{50 * r['rmse_spread']:.2f})", f"{100 * r['p95']:.1f}", f"{100 * r['max']:.0f}", f"{100 * r['worst_block']:.1f}",
              "yes" if i in front else ""] for i, r in enumerate(rs)],
            ["around", "knob", "value", "voxels", "bake s", "voxelize / photons / propagation / lights / texels s",
             "peak RSS MiB (before)", "rel. RMSE %", "p95 %", "max %", "worst 8x8 %", "on front"]), ""]
    with open(os.path.join(args.out, "tradeoff.md"), "w") as f:
        f.write("\n".join(lines))
    plot(rows, os.path.join(args.out, "tradeoff.png"))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
