"""Error against time: lightcuts frames (the whole chain: voxel solve, VPLs
and light tree, the frame; epsilon 1-5%, at each preset) and the path
tracer (a sweep of samples per pixel), each against a converged path-traced
reference of the same camera, on the Cornell box and the walkthrough
scene. Error: relative RMSE of luminance over the pixels that do not see a
lamp (common.rel_rmse); the reference's own noise is subtracted.

The lightcuts frame is biased (the voxel solution's error, the bounded
near-field term), so its error has a floor; the path tracer's falls as
1/sqrt(time) and below. The table says which reaches a target first.

    python bench/error_time.py [--size 128] [--target 0.03] [--json]
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from common import cached_reference, emit, rel_rmse
from baker.scene import camera_for  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--spp", default="16,64,256,1024")
    ap.add_argument("--target", type=float, default=0.03)
    ap.add_argument("--scenes", default="cornell_box,walkthrough")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    import baker
    from baker.lights import build_lights
    from baker.presets import lightcuts_config
    from baker.render import camera_array
    from baker.render.lightcuts_frame import render_lightcuts
    from baker.render.pathtrace import pathtrace
    from baker.scene import Prepared, build_scene_bvh, pack
    s = args.size
    summary = []
    for name in args.scenes.split(","):
        scene = baker.load_scene(name)
        bvh, surf = build_scene_bvh(scene), pack(scene)
        cam = camera_array(camera_for(scene, None, bvh), s, s)
        pathtrace(bvh, surf, camera_array(camera_for(scene, None, bvh), 8, 8), 8, 8, 2)  # compile
        if name == args.scenes.split(",")[0]:  # compile the solver and the frame outside the timings
            warm = baker.solve(scene, baker.solver_config("preview", resolution=8, photons=2000), bvh=bvh,
                               surfaces=surf)
            lc = lightcuts_config("preview")
            render_lightcuts(bvh, surf, build_lights(Prepared(scene, bvh, surf), warm, lc),
                             camera_array(camera_for(scene, None, bvh), 8, 8), 8, 8, lc.epsilon, lc.cap)
        ref, lamp, ref_noise, _ = cached_reference(name, scene, bvh, surf, cam, s, args.ref_spp)
        rows = []
        pt_pts = []
        for n in [int(x) for x in args.spp.split(",")]:
            r = pathtrace(bvh, surf, cam, s, s, n, seed=1)
            e = rel_rmse(r.image, ref, lamp, ref_noise)
            pt_pts.append((n, r.seconds, e))
            rows.append(["path tracer", f"{n} spp", f"{r.seconds:.2f}", f"{100 * e:.2f}"])
        lc_pts = []
        for preset in ("preview", "default", "high"):
            t0 = time.perf_counter()
            sol = baker.solve(scene, baker.solver_config(preset), bvh=bvh, surfaces=surf)
            t_solve = time.perf_counter() - t0
            for eps in (0.05, 0.02, 0.01):
                lc = lightcuts_config(preset, epsilon=eps)
                t1 = time.perf_counter()
                lights = build_lights(Prepared(scene, bvh, surf), sol, lc)
                img, st = render_lightcuts(bvh, surf, lights, cam, s, s, lc.epsilon, lc.cap)
                t_frame = time.perf_counter() - t1
                e = rel_rmse(img, ref, lamp, ref_noise)
                total = t_solve + t_frame
                lc_pts.append((preset, eps, total, e))
                rows.append([f"lightcuts {preset}", f"eps {eps:g}", f"{total:.2f} ({t_solve:.1f} solve)",
                             f"{100 * e:.2f}"])
        emit(args, f"{name} {s}x{s}: error against time (reference {args.ref_spp} spp, its noise "
                   f"{100 * ref_noise:.2f}% subtracted)", rows, ["method", "setting", "seconds", "rel. RMSE %"])
        # time to the target: the path tracer by a power law over its sweep, lightcuts the fastest setting under it
        ns, ts, es = map(np.array, zip(*pt_pts))
        b, a = np.polyfit(np.log(ns), np.log(es), 1)
        n_t = math.exp((math.log(args.target) - a) / b)
        t_pt = n_t * float(np.mean(ts / ns))
        ok = [p for p in lc_pts if p[3] <= args.target]
        best = min(ok, key=lambda p: p[2]) if ok else None
        floor = min(p[3] for p in lc_pts)
        summary.append([name, f"{t_pt:.1f} ({n_t:.0f} spp)",
                        f"{best[2]:.1f} ({best[0]}, eps {best[1]:g})" if best else f"not reached (best {100 * floor:.1f}%)",
                        f"{t_pt / best[2]:.1f}x" if best else "-"])
    emit(args, f"Time to {100 * args.target:g}% relative RMSE, {s}x{s}", summary,
         ["scene", "path tracer s", "lightcuts s", "lightcuts faster by"])


if __name__ == "__main__":
    main()
