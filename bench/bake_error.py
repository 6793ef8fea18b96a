"""Lightmap error against bake time, texel by texel: the Cornell box baked
at a fixed texel density (128 texels per metre, as the Blender Cycles
figures were measured) at each preset and lightcuts epsilon, against a
converged bake of our own with the same texel layout (the high preset,
epsilon 0.002, 4x its direct VPLs, every texel whose light differs from a
neighbour's by more than 1% the mean of a 4 x 4 grid of points over its
square: what a texel stands for is the light over its square, not at one
point). Error: relative RMSE of the texels'
irradiance (luminance) over the covered texels not on an emitter,
divided by the reference's mean there. Smoothness: of the pairs of
side-by-side texels whose converged light differs by under 0.5%, the
share whose baked light differs by under 1%, and the 99th percentile of
their relative step. Times are whole bakes (voxel solve, texels, atlas),
in process, after a warm-up.

    python bench/bake_error.py [--density 128] [--json]
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from common import emit

LUM = np.array([0.2126, 0.7152, 0.0722])


def neighbour_pairs(texels, keep):
    """(a, b) texel indices of every pair of side-by-side texels of one
    map (row or column neighbours), both kept."""
    pairs = []
    for o, n in zip(texels.map_offsets[:len(texels.map_size)], texels.map_size):
        idx = o + np.arange(n * n).reshape(n, n)
        pairs += [np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], 1),
                  np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], 1)]
    p = np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)
    p = p[keep[p[:, 0]] & keep[p[:, 1]]]
    return p[:, 0], p[:, 1]


def rel_step(lum, a, b):
    return np.abs(lum[a] - lum[b]) / np.maximum(np.maximum(lum[a], lum[b]), 1e-300)


def texel_values(scene, config):
    from baker.bake.pipeline import bake_scene
    t = time.perf_counter()
    texels = bake_scene(scene, config).texels
    return texels, time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--density", type=float, default=128.0, help="texels per scene unit (the Cornell box is in metres)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    import baker
    from baker.presets import PRESETS, bake_config, lightcuts_config
    scene = baker.load_scene("cornell_box")
    texel_values(scene, bake_config("preview", texel_density=16))  # compile
    high = lightcuts_config("high")
    ref, t_ref = texel_values(scene, bake_config("high", texel_density=args.density, epsilon=0.002,
                                                 direct_vpls=4 * high.direct_vpls, texel_samples=4,
                                                 texel_contrast=0.01))
    emitter = scene.emission[scene.material_ids].max(axis=1) > 0
    keep = ref.covered & ~ref.inside & (ref.texel_tri >= 0)
    keep &= ~emitter[np.maximum(ref.texel_tri, 0)]
    r = ref.values[keep] @ LUM
    m = r.mean()
    # smooth pairs: neighbours whose converged light differs by under half a percent (no shadow edge, no
    # contact between them); a bake's neighbours there should differ by under 1% (what the eye reads as noise)
    pa, pb = neighbour_pairs(ref, keep)
    ref_lum = ref.values @ LUM
    smooth = rel_step(ref_lum, pa, pb) < 0.005
    pa, pb = pa[smooth], pb[smooth]
    rows = []
    # (preset, epsilon, grid side, adaptive agreement, anti-aliasing contrast): the presets as shipped and around them
    d, h = PRESETS["default"], PRESETS["high"]
    n_d, n_h, aa = d.texel_samples, h.texel_samples, h.texel_contrast
    runs = ([("preview", None, 1, 0.0, 0.0)]
            + [("default", e, n, t, aa) for e in (0.05, 0.02, 0.01) for n, t in
               ((1, 0.0), (n_d, 0.0), (n_d, 0.1))]
            + [("default", e, n_d, d.texel_interpolate, d.texel_contrast) for e in (0.02, 0.01)]
            + [("high", e, n, 0.0, aa) for e in (0.02, 0.01) for n in (1, n_h)])
    for preset, eps, n, interp, contrast in runs:
        tx, secs = texel_values(scene, bake_config(preset, texel_density=args.density, epsilon=eps,
                                                   texel_samples=n, texel_interpolate=interp,
                                                   texel_contrast=contrast))
        if len(tx.values) != len(ref.values):
            raise SystemExit("texel layouts differ: cannot compare texel by texel")
        a = tx.values[keep] @ LUM
        e = math.sqrt(np.mean((a - r) ** 2)) / m
        step = rel_step(tx.values @ LUM, pa, pb)
        rows.append([preset, "voxels" if eps is None else f"lightcuts, eps {eps:g}",
                     "-" if n == 1 else f"{n}x{n} above {contrast:.0%}",
                     "-" if eps is None else "every texel" if interp == 0 else f"adaptive, {interp:.0%}", f"{secs:.2f}",
                     f"{100 * e:.2f}", f"{100 * np.percentile(np.abs(a - r) / m, 95):.1f}",
                     f"{np.mean(step < 0.01):.1%}", f"{100 * np.percentile(step, 99):.2f}"])
    emit(args, f"Cornell box lightmap texels ({int(keep.sum()):,} texels at {args.density:g} per metre) against "
               f"a converged bake of ours ({t_ref:.0f} s)", rows,
         ["preset", "texel values", "edge texels", "shading", "bake s", "rel. RMSE %", "95th pct |error| / mean %",
          f"smooth pairs within 1% (of {len(pa):,})", "p99 step %"])


if __name__ == "__main__":
    main()
