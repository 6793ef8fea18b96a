"""Headless snapshots: a bake rendered offscreen through standalone EGL
(Mesa llvmpipe where there is no GPU), read back as linear radiance.

The frame is drawn at `samples` times the size on each axis into a float
framebuffer and box-filtered down: the same 4 x 4 points per pixel as the
CPU render of a bake (baker.render.lightmap_view), so the two compare pixel by
pixel.
"""
from __future__ import annotations

import numpy as np

MAX_SIDE = 4096  # the supersampled framebuffer's largest side


def supersampling(width, height, samples=4) -> int:
    return max(1, min(int(samples), MAX_SIDE // max(width, height)))


def render_offscreen(ctx, renderer, camera, width, height, mode="lightmap", samples=4, bicubic=False, objects=(),
                     probes=False):
    """Linear radiance (height, width, 3) float32 (mode 'lightmap'; the
    debug views' colours otherwise), rows top to bottom."""
    s = supersampling(width, height, samples)
    w, h = width * s, height * s
    color = ctx.renderbuffer((w, h), 4, dtype="f4")
    depth = ctx.depth_renderbuffer((w, h))
    fbo = ctx.framebuffer([color], depth)
    try:
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
        renderer.render(camera, w, h, mode, tonemap=False, bicubic=bicubic, objects=objects, probes=probes)
        raw = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(h, w, 4)[::-1, :, :3]
    finally:
        fbo.release()
        color.release()
        depth.release()
    img = raw.reshape(height, s, width, s, 3).mean(axis=(1, 3))
    return np.ascontiguousarray(np.maximum(img, 0.0), np.float32)


def snapshot(bake, camera=None, width=512, height=512, mode="lightmap", samples=4, bicubic=False, ctx=None,
             frames=64, per_frame=16, progress=None, objects=(), probes=False):
    """A bake's snapshot from `camera` (a Camera, name, index or None: the
    bake's first), on a standalone EGL context (or `ctx`). mode 'preview':
    the progressive instant radiosity after `frames` frames of `per_frame`
    VPLs, at the pixels' centres (as the CPU's). objects: moving objects
    (objects.Sphere) lit by the bake's probes; probes: the probes drawn as
    small spheres lit by their SH (objects.ProbeGridView)."""
    from baker.scene import camera_for
    from .context import headless_context
    from .renderer import Renderer
    own = ctx is None
    ctx = ctx or headless_context()
    try:
        r = Renderer(ctx, bake)
        cam = camera if hasattr(camera, "forward") else camera_for(bake.scene, camera)
        if mode == "preview":
            from .preview import Preview
            pv = Preview(ctx, r, cam, width, height, per_frame=per_frame)
            for _ in range(frames):
                if not pv.frame():
                    break
                if progress is not None:
                    progress(1)
            img = pv.image()
            pv.release()
        else:
            img = render_offscreen(ctx, r, cam, width, height, mode, samples, bicubic, objects, probes)
        r.release()
        return img
    finally:
        if own:
            ctx.release()
