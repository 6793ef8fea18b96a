"""Moving objects lit by the bake's irradiance probes (baker/probes/): a
diffuse sphere placed in the scene, drawn with shaders/probe_object.*.

The probes' irradiance maps and distance moments go to the GPU once as
float textures (probe-major, WIDTH texels a row). Per object, the CPU
decides which probes around it count: valid ones that its centre sees (a
ray against the scene's BVH), the exact test that keeps an object beside
a wall lit by its own side only; the shader reads that mask and weighs
the rest as baker/probes/sample.py does. A sphere larger than a probe
cell gets that per-point sum over its whole surface once per position,
into an octahedral map of its normals (a sphere's point is a function of
its normal), and its pixels read the map; a smaller one reads its probes
blended at its centre (probe/sample.py: object_map).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

WIDTH = 4096   # texels per row of the packed probe textures (shaders/probe_object.frag)
SURFACE_MAP = 128   # texels a side of a large sphere's map: its mean is the per-pixel sum's within 0.01% (64: 0.5%)


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


def probe_seen(grid, center, radius, bvh) -> np.ndarray:
    """(count,) uint8: probe_mask over the whole grid (0 outside the
    sphere's cells), as sphere_map takes it."""
    lo, mask = probe_mask(grid, center, radius, bvh)
    dims = np.asarray(grid.dims, np.int64)
    seen = np.zeros(tuple(dims[::-1]), np.uint8)   # z, y, x: the flat order x fastest
    nz, ny, nx = mask.shape
    seen[lo[2]:lo[2] + nz, lo[1]:lo[1] + ny, lo[0]:lo[0] + nx] = mask
    return seen.reshape(-1)


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
        self.maps = {}   # (kind, i) -> [side, texture, (centre, radius) it holds]
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
        """Each sphere, shaded from one irradiance map over its normals
        (_object_map), one read a pixel."""
        for i, s in enumerate(spheres):
            size, tex = self._object_map(i, s)
            prog, vao = self._program(tonemap, True)
            self._uniforms(prog, vp, exposure)
            tex.use(6)
            prog["u_object_map"].value = 6
            prog["u_map_size"].value = int(size)
            prog["u_center"].value = tuple(float(v) for v in s.center)
            prog["u_radius"].value = float(s.radius)
            prog["u_albedo"].value = tuple(float(v) for v in s.albedo)
            vao.render(moderngl_triangles())

    def _uniforms(self, prog, vp, exposure):
        g = self.grid
        for name, value in (("u_origin", tuple(float(v) for v in g.origin)), ("u_spacing", float(g.spacing)),
                            ("u_dims", tuple(int(v) for v in g.dims)), ("u_irradiance", 3), ("u_depth", 4),
                            ("u_mask", 5), ("u_irr_size", int(g.irradiance.shape[1])),
                            ("u_depth_size", int(g.depth.shape[1])), ("u_exposure", float(exposure))):
            if name in prog:
                prog[name].value = value
        if "u_view_proj" in prog:
            prog["u_view_proj"].write(vp.T.astype(np.float32).tobytes())
        self.irr.use(3)
        self.depth.use(4)

    def _object_map(self, i, s):
        """(side, texture): the sphere's irradiance over its normals. No
        larger than a probe cell: its probes blended at its centre
        (object_map, the probes' map size); larger: the per-point sum at
        each of SURFACE_MAP squared normals' points (sphere_map), its
        probes masked by what its centre sees. The i-th object of each
        kind has one texture for the viewer's life, rewritten when it
        moves. The map is made on the CPU: a GPU pass into a texture the
        same frame reads made llvmpipe stop and finish it (8 ms a frame
        while an object moved, against 2 ms here)."""
        import moderngl
        from baker.probes.sample import object_map, sphere_map
        kind = "blended" if s.radius <= self.grid.spacing else "surface"
        key = (tuple(s.center), float(s.radius))
        if (kind, i) not in self.maps:
            size = self.grid.irradiance.shape[1] if kind == "blended" else SURFACE_MAP
            tex = self.ctx.texture((size, size), 3, dtype="f4")
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.maps[(kind, i)] = [size, tex, None]
        size, tex, held = self.maps[(kind, i)]
        if held != key:
            if kind == "blended":
                m = object_map(self.grid, s.center, self.bvh)
            else:
                m = sphere_map(self.grid, s.center, s.radius, probe_seen(self.grid, s.center, s.radius, self.bvh),
                               size)
            tex.write(np.ascontiguousarray(m, np.float32).tobytes())
            self.maps[(kind, i)][2] = key
        return size, tex

    def release(self):
        for prog, vao in self.programs.values():
            vao.release()
            prog.release()
        for obj in (self.irr, self.depth, self.vbo, *(m[1] for m in self.maps.values())):
            obj.release()
