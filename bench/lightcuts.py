"""Lightcuts benchmark: frame time and cut size against the VPL count (the
Cornell box, direct VPLs 1k .. 1M plus the voxels' indirect ones), the
speed-up over the brute-force sum on the same VPLs, the light tree's build
time, and the Cornell box at 512x512 (solve + frame).

    python bench/lightcuts.py [--size 64] [--max-vpls 1048576] [--json]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from common import emit
from baker.scene import camera_for  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=64, help="frame size for the VPL sweep")
    ap.add_argument("--max-vpls", type=int, default=1 << 20)
    ap.add_argument("--brute-at", type=int, default=100_000, help="VPL count of the brute-force comparison")
    ap.add_argument("--full", type=int, default=512, help="the full frame's size (0: skip)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    import baker
    from baker.lights import Lights, build_lights, build_tree, make_vpls
    from baker.presets import lightcuts_config
    from baker.render import camera_array
    from baker.render.lightcuts_frame import render_lightcuts
    from baker.scene import Prepared, build_scene_bvh, pack
    scene = baker.load_scene("cornell_box")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    sol = baker.solve(scene, baker.solver_config("default"), bvh=bvh, surfaces=surf)
    s = args.size
    cam = camera_array(camera_for(scene, None), s, s)
    rows, times, sizes = [], [], []
    n = 1024
    counts = []
    while n <= args.max_vpls:
        counts.append(n)
        n *= 4
    build_tree(make_vpls(scene, sol, surf, 64, 0, 0), 0)  # compile the build outside the timings
    for n in counts:
        vpls = make_vpls(scene, sol, surf, n, 0, 0)
        t = time.perf_counter()
        tree = build_tree(vpls, 0)
        tb = time.perf_counter() - t
        lights = Lights(vpls, tree)
        render_lightcuts(bvh, surf, lights, cam, 8, 8)  # warm
        t = time.perf_counter()
        img, st = render_lightcuts(bvh, surf, lights, cam, s, s, 0.02, 1000)
        tf = time.perf_counter() - t
        times.append(tf)
        sizes.append(len(vpls))
        rows.append([f"{len(vpls):,}", f"{tb:.3f}", f"{tf:.2f}", f"{st.cut_mean:.0f}", st.cut_max,
                     f"{st.shadow_rays_per_pixel:.0f}"])
    slope = np.polyfit(np.log(sizes), np.log(times), 1)[0] if len(times) > 1 else 0
    emit(args, f"Lightcuts frame {s}x{s} (Cornell box, epsilon 0.02, cap 1000) against VPL count; "
               f"log-log slope of frame time {slope:.2f}", rows,
         ["VPLs", "tree build s", "frame s", "cut mean", "cut max", "shadow rays/pixel"])
    # brute force at ~brute_at VPLs, on a small frame
    vpls = make_vpls(scene, sol, surf, max(1, args.brute_at - int((sol.radiosity > sol.voxels.emission).any(axis=1).sum())),
                     0, 0)
    lights = Lights(vpls, build_tree(vpls, 0))
    b = 24
    cam_b = camera_array(camera_for(scene, None), b, b)
    t = time.perf_counter()
    fast, st = render_lightcuts(bvh, surf, lights, cam_b, b, b, 0.02, 1000, aa=False)
    tl = time.perf_counter() - t
    t = time.perf_counter()
    slow, _ = render_lightcuts(bvh, surf, lights, cam_b, b, b, brute=True, aa=False)
    tbf = time.perf_counter() - t
    lum = np.array([0.2126, 0.7152, 0.0722])
    rel = np.abs(fast - slow) @ lum / np.maximum(slow @ lum, 1e-12)
    emit(args, f"Speed-up over the brute force ({len(vpls):,} VPLs, {b}x{b}, no anti-aliasing)",
         [[f"{tl:.3f}", f"{tbf:.2f}", f"{tbf / tl:.0f}x", f"{np.median(rel):.4f}", f"{np.percentile(rel, 99):.4f}"]],
         ["lightcuts s", "brute force s", "speed-up", "median rel. error", "99th pct"])
    if args.full:
        f = args.full
        t0 = time.perf_counter()
        sol2 = baker.solve(scene, baker.solver_config("default"), bvh=bvh, surfaces=surf)
        t1 = time.perf_counter()
        from baker.render.frame import gathered_lights
        lc = lightcuts_config("default")
        lights, bounce = gathered_lights(build_lights(Prepared(scene, bvh, surf), sol2, lc, tree=False), sol2, lc)
        t2 = time.perf_counter()
        img, st = render_lightcuts(bvh, surf, lights, camera_array(camera_for(scene, None), f, f), f, f,
                                   lc.epsilon, lc.cap, bounce=bounce)
        t3 = time.perf_counter()
        emit(args, f"Cornell box {f}x{f}, default preset: solve + lights + lightcuts frame (its bounced light "
                   f"gathered by {lc.gather} rays)",
             [[f"{t1 - t0:.2f}", f"{t2 - t1:.2f}", f"{t3 - t2:.2f}", f"{t3 - t0:.2f}", f"{len(lights.vpls):,}",
               f"{st.cut_mean:.0f}", st.edge_pixels]],
             ["solve s", "lights s", "frame s", "total s", "VPLs in the cuts", "cut mean", "edge pixels (16 spp)"])


if __name__ == "__main__":
    main()
