"""Moving objects lit by the bake's irradiance probes (baker/probes/): a
diffuse sphere placed in the scene, drawn with shaders/probe_object.*.

The probes' irradiance maps and distance moments go to the GPU once as
float textures (probe-major, WIDTH texels a row). Per object, the CPU
decides which probes around it count: valid ones that its centre sees (a
ray against the scene's BVH), the exact test that keeps an object beside
a wall lit by its own side only; the shader reads that mask and weighs
the rest as baker/probes/sample.py does.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

WIDTH = 4096   # texels per row of the packed probe textures (shaders/probe_object.frag)


@dataclass(frozen=True)
class Sphere:
    """A diffuse sphere: centre (3,), radius, albedo (3,)."""
    center: tuple
    radius: float
    albedo: tuple = (0.8, 0.8, 0.8)


def sphere_mesh(subdiv: int = 4) -> np.ndarray:
    """(3 m, 3) float32: a unit icosphere's triangles, counter-clockwise
    seen from outside (its points are its normals)."""
    from scenes.generate import icosphere
    pos, tri = icosphere(subdiv, 1.0)
    pos = np.asarray(pos, np.float64)
    pos /= np.linalg.norm(pos, axis=1)[:, None]
    return np.ascontiguousarray(pos[np.asarray(tri).reshape(-1)], np.float32)


def probe_mask(grid, center, radius, bvh):
    """(lo (3,) int, mask (nz, ny, nx) uint8): over the probes whose cells
    the sphere can touch, 1 where a probe is valid and seen from the
    centre (through glass counts as seen)."""
    from baker.probes.sample import _sees
    dims = np.asarray(grid.dims, np.int64)
    c = np.asarray(center, np.float64)
    lo = np.clip(np.floor((c - radius - grid.origin) / grid.spacing).astype(np.int64), 0, dims - 1)
    hi = np.clip(np.floor((c + radius - grid.origin) / grid.spacing).astype(np.int64) + 1, 0, dims - 1)
    k = np.stack(np.meshgrid(*[np.arange(a, b + 1) for a, b in zip(lo, hi)], indexing="ij"), -1).reshape(-1, 3)
    p = grid.origin + grid.spacing * k
    flat = k[:, 0] + dims[0] * (k[:, 1] + dims[1] * k[:, 2])
    ok = grid.valid[flat] & (_sees(bvh, np.repeat(c[None], len(k), 0), p) > 0)
    shape = tuple(int(b - a + 1) for a, b in zip(lo, hi))   # (x, y, z)
    return lo, ok.reshape(shape).transpose(2, 1, 0).astype(np.uint8)   # z, y, x: a 3D texture's layout


def moderngl_triangles():
    import moderngl
    return moderngl.TRIANGLES


def _packed(values: np.ndarray, channels: int) -> np.ndarray:
    """Probe-major texels (N, ..., channels) as rows of WIDTH texels."""
    flat = np.ascontiguousarray(values, np.float32).reshape(-1, channels)
    rows = -(-len(flat) // WIDTH)
    out = np.zeros((rows * WIDTH, channels), np.float32)
    out[:len(flat)] = flat
    return out.reshape(rows, WIDTH, channels)


class ProbeObjects:
    """Draws spheres lit by a bake's probes into the bound framebuffer."""

    def __init__(self, ctx, bake):
        from baker.errors import VoxgiError
        from baker.scene.prepared import prepare
        if bake.probes is None:
            raise VoxgiError("the bake holds no irradiance probes: bake it again without --no-probes")
        import moderngl
        self.ctx = ctx
        self.grid = g = bake.probes
        irr = _packed(g.irradiance, 3)
        depth = _packed(g.depth, 2)
        if max(len(irr), len(depth)) > 16384:
            raise VoxgiError(f"{g.count:,} probes are more than the viewer's textures hold")
        self.irr = ctx.texture((WIDTH, len(irr)), 3, irr.tobytes(), dtype="f4")
        self.depth = ctx.texture((WIDTH, len(depth)), 2, depth.tobytes(), dtype="f4")
        for t in (self.irr, self.depth):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.vbo = ctx.buffer(sphere_mesh().tobytes())
        self.programs = {}
        self.masks = {}   # (centre, radius, blended) -> (first probe, mask or map texture) of the object drawn last
        self.bvh = prepare(bake.scene).bvh.arrays

    def _program(self, tonemap, blended):
        key = (bool(tonemap), bool(blended))
        if key not in self.programs:
            from .context import build_program
            prog = build_program(self.ctx, "probe_object.vert", "probe_object.frag",
                                 {"TONEMAP": int(tonemap), "BLENDED": int(blended)})
            self.programs[key] = (prog, self.ctx.vertex_array(prog, [(self.vbo, "3f", "in_position")]))
        return self.programs[key]

    def draw(self, vp, spheres, tonemap=True, exposure=1.0):
        """Each sphere: no larger than a probe cell, shaded by its probes
        blended at its centre into one map (object_map: one read a pixel);
        larger, every pixel weighs the probes of its own cell."""
        for s in spheres:
            blended = s.radius <= self.grid.spacing
            prog, vao = self._program(tonemap, blended)
            self._uniforms(prog, vp, exposure)
            lo, tex = self._mask_or_map(s, blended)
            tex.use(5 if not blended else 6)
            if blended:
                prog["u_object_map"].value = 6
            else:
                prog["u_mask_lo"].value = tuple(int(v) for v in lo)
            prog["u_center"].value = tuple(float(v) for v in s.center)
            prog["u_radius"].value = float(s.radius)
            prog["u_albedo"].value = tuple(float(v) for v in s.albedo)
            vao.render(moderngl_triangles())

    def _uniforms(self, prog, vp, exposure):
        g = self.grid
        prog["u_view_proj"].write(vp.T.astype(np.float32).tobytes())
        for name, value in (("u_origin", tuple(float(v) for v in g.origin)), ("u_spacing", float(g.spacing)),
                            ("u_dims", tuple(int(v) for v in g.dims)), ("u_irradiance", 3), ("u_depth", 4),
                            ("u_mask", 5), ("u_irr_size", int(g.irradiance.shape[1])),
                            ("u_depth_size", int(g.depth.shape[1])), ("u_exposure", float(exposure))):
            if name in prog:
                prog[name].value = value
        self.irr.use(3)
        self.depth.use(4)

    def _mask_or_map(self, s, blended):
        """(first probe, texture): the object's probe mask, or its blended
        map; kept while the object stands still."""
        import moderngl
        from baker.probes.sample import object_map
        key = (tuple(s.center), float(s.radius), blended)
        if key not in self.masks:
            for _, old in self.masks.values():
                old.release()
            self.masks.clear()
            if blended:
                m = np.ascontiguousarray(object_map(self.grid, s.center, self.bvh), np.float32)
                tex = self.ctx.texture((m.shape[1], m.shape[0]), 3, m.tobytes(), dtype="f4")
                lo = np.zeros(3, np.int64)
            else:
                lo, mask = probe_mask(self.grid, s.center, s.radius, self.bvh)
                tex = self.ctx.texture3d(mask.shape[::-1], 1, mask.tobytes(), dtype="u1")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.masks[key] = (lo, tex)
        return self.masks[key]

    def release(self):
        for prog, vao in self.programs.values():
            vao.release()
            prog.release()
        for obj in (self.irr, self.depth, self.vbo, *(t for _, t in self.masks.values())):
            obj.release()
