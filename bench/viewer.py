"""Viewer benchmark: frame time of the walkthrough's lightmap view at
1280x720 on this machine's OpenGL (llvmpipe where there is no GPU), drawn
as the window draws it (tone-mapped, into an 8-bit framebuffer), over
each of the bake's cameras; and the progressive preview's VPLs per second
(a cube shadow map and a shading pass each) at the same size.

    python bench/viewer.py [--frames 100] [--scenes cornell_box walkthrough] [--json]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

from common import ROOT, emit
from baker.scene import camera_for  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--scenes", nargs="+", default=["cornell_box", "walkthrough"])
    ap.add_argument("--preset", default="preview")
    ap.add_argument("--preview-frames", type=int, default=4, help="preview frames (of 16 VPLs) to time")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    from baker.bake import read_bake
    from viewer.context import headless_context
    from viewer.renderer import Renderer
    ctx = headless_context()
    rows = []
    tmp = tempfile.mkdtemp(prefix="voxgi-bench-")
    for scene in args.scenes:
        path = os.path.join(tmp, scene + ".glb")
        subprocess.run([sys.executable, "-m", "baker", "bake", scene, "--preset", args.preset, "-o", path],
                       check=True, capture_output=True, cwd=ROOT)
        bake = read_bake(path)
        r = Renderer(ctx, bake)
        color = ctx.renderbuffer((args.width, args.height), 4)
        depth = ctx.depth_renderbuffer((args.width, args.height))
        fbo = ctx.framebuffer([color], depth)
        fbo.use()
        times = []
        for cam in bake.scene.cameras or [camera_for(bake.scene, None)]:
            for _ in range(3):  # warm-up: shader variants, texture upload
                fbo.clear(depth=1.0)
                r.render(cam, args.width, args.height)
            ctx.finish()
            t = time.perf_counter()
            for _ in range(args.frames):
                fbo.clear(depth=1.0)
                r.render(cam, args.width, args.height)
            ctx.finish()
            times.append((time.perf_counter() - t) / args.frames)
        fbo.release()
        color.release()
        depth.release()
        from viewer.preview import Preview
        pv = Preview(ctx, r, bake.scene.cameras[0] if bake.scene.cameras else camera_for(bake.scene, None), args.width,
                     args.height, per_frame=16)
        pv.frame()
        ctx.finish()
        t = time.perf_counter()
        n_frames = max(1, args.preview_frames)
        for _ in range(n_frames):
            pv.frame()
        ctx.finish()
        vps = 16 * n_frames / (time.perf_counter() - t)
        pv.release()
        r.release()
        ms = [1000 * t for t in times]
        rows.append([scene, f"{len(bake.scene.vertices) // 3:,}", len(bake.pages), len(times),
                     f"{min(ms):.1f}-{max(ms):.1f}", f"{1000 / max(ms):.0f}-{1000 / min(ms):.0f}", f"{vps:.0f}"])
    info = ctx.info
    emit(args, f"Walkthrough frame time at {args.width}x{args.height} ({info['GL_RENDERER']}, "
               f"{os.environ.get('LP_NUM_THREADS', 'all')} llvmpipe threads)", rows,
         ["scene", "triangles", "pages", "cameras", "ms/frame (min-max over cameras)", "fps", "preview VPLs/s"])


if __name__ == "__main__":
    main()
