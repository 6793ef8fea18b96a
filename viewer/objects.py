"""Moving objects lit by the bake's irradiance probes (baker/probes/): a
diffuse sphere placed in the scene, drawn with shaders/probe_object.*;
the bake's dynamic meshes (voxbake bake --dynamic NODE), drawn with
shaders/probe_mesh.*; and the probe view, the probes themselves
(shaders/probe_grid.*).

Per object, the CPU decides which probes around it count: valid ones
that its centre sees (a ray against the scene's BVH), the exact test
that keeps an object beside a wall lit by its own side only. It then
makes the object's irradiance map over its normals, which the shader
reads once a pixel: a sphere larger than a probe cell gets
baker/probes/sample.py's per-point sum at each of the map's normals'
points on it (sphere_map: a sphere's point is a function of its
normal); a smaller one its probes blended at its centre (object_map).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

WIDTH = 4096   # texels per row of the probe view's packed SH texture (shaders/probe_grid.frag)
SURFACE_MAP = 128   # texels a side of a large sphere's map: its mean is the per-pixel sum's within 0.01% (64: 0.5%)
MOVING_MAP = 64     # ... while it moves in the window (0.5 ms to make against 2.0-2.3), the full map once it stops
# shadow rays to each lamp triangle from each point (a sphere's visibility map texel, a vertex): the penumbra's
# steps. The walkthrough's 64 x 64 moving map under its eight lamp triangles: 2.7 ms with 1, 6.3 with 16
OBJECT_LAMP_RAYS = 4


@dataclass(frozen=True)
class Sphere:
    """A diffuse sphere: centre (3,), radius, albedo (3,)."""
    center: tuple
    radius: float
    albedo: tuple = (0.8, 0.8, 0.8)


@dataclass(frozen=True)
class Placed:
    """The bake's dynamic mesh number `index` (bake.scene.dynamic), moved
    by `offset` (3,) from where the file has it."""
    index: int
    offset: tuple = (0.0, 0.0, 0.0)


def placed_at(mesh, index, at) -> Placed:
    """`mesh` (scene.DynamicMesh, number `index`) moved so that the centre
    of its bounds is at `at`."""
    return Placed(index, tuple(float(v) for v in np.asarray(at, np.float64) - mesh_center(mesh)))


def mesh_center(mesh) -> np.ndarray:
    """The centre of a dynamic mesh's bounds, float64 (3,)."""
    v = mesh.vertices
    return 0.5 * (v.min(axis=0).astype(np.float64) + v.max(axis=0).astype(np.float64))


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
    return lo, ok.reshape(shape).transpose(2, 1, 0).astype(np.uint8)   # z, y, x: the grid's flat order, x fastest


def probe_seen(grid, center, radius, bvh) -> np.ndarray:
    """(count,) uint8: probe_mask over the whole grid (0 outside the
    sphere's cells), as sphere_map takes it."""
    lo, mask = probe_mask(grid, center, radius, bvh)
    dims = np.asarray(grid.dims, np.int64)
    seen = np.zeros(tuple(dims[::-1]), np.uint8)   # z, y, x: the flat order x fastest
    nz, ny, nx = mask.shape
    seen[lo[2]:lo[2] + nz, lo[1]:lo[1] + ny, lo[0]:lo[0] + nx] = mask
    return seen.reshape(-1)


def bordered(m) -> np.ndarray:
    """(s + 2, s + 2, 3) float32: an octahedral map (s, s, 3) with a
    one-texel border that repeats the texels across each fold (the edge
    texels' mirror images, the opposite corners: probes/sample._wrap), so
    that the GPU's own bilinear filter reads it as the octahedron joins."""
    m = np.asarray(m, np.float32)
    out = np.empty((m.shape[0] + 2, m.shape[1] + 2, 3), np.float32)
    out[1:-1, 1:-1] = m
    out[0, 1:-1], out[-1, 1:-1] = m[0, ::-1], m[-1, ::-1]
    out[1:-1, 0], out[1:-1, -1] = m[::-1, 0], m[::-1, -1]
    out[0, 0], out[0, -1], out[-1, 0], out[-1, -1] = m[-1, -1], m[-1, 0], m[0, -1], m[0, 0]
    return out


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

    def __init__(self, ctx, bake, interactive=False, prepared=None):
        from baker.errors import VoxgiError
        from baker.probes.sample import probe_lights
        from baker.scene.prepared import prepare
        if bake.probes is None:
            raise VoxgiError("the bake holds no irradiance probes: bake it again without --no-probes")
        prepared = prepared if prepared is not None else prepare(bake.scene)
        self.ctx = ctx
        self.grid = bake.probes
        # the sun, punctual lights and lamps, exact at each point
        self.lights = probe_lights(self.grid, prepared, OBJECT_LAMP_RAYS)
        self.vbo = ctx.buffer(sphere_mesh().tobytes())
        self.programs = {}
        self.maps = {}   # (kind, i, side) -> [texture, (centre, radius) it holds]
        self.shown = {}  # (kind, i) -> (side, (centre, radius)) of the map drawn last
        self.interactive = interactive   # the window: a coarser map while a large sphere moves
        self.bvh = prepared.bvh.arrays

    def _program(self, tonemap):
        key = bool(tonemap)
        if key not in self.programs:
            from .context import build_program
            prog = build_program(self.ctx, "probe_object.vert", "probe_object.frag", {"TONEMAP": int(tonemap)})
            self.programs[key] = (prog, self.ctx.vertex_array(prog, [(self.vbo, "3f", "in_position")]))
        return self.programs[key]

    def draw(self, vp, spheres, tonemap=True, exposure=1.0):
        """Each sphere, shaded from one irradiance map over its normals
        (_object_map), one read a pixel."""
        for i, s in enumerate(spheres):
            size, tex = self._object_map(i, s)
            prog, vao = self._program(tonemap)
            prog["u_view_proj"].write(vp.T.astype(np.float32).tobytes())
            if "u_exposure" in prog:
                prog["u_exposure"].value = float(exposure)
            tex.use(6)
            prog["u_object_map"].value = 6
            prog["u_map_size"].value = int(size)
            prog["u_center"].value = tuple(float(v) for v in s.center)
            prog["u_radius"].value = float(s.radius)
            prog["u_albedo"].value = tuple(float(v) for v in s.albedo)
            vao.render(moderngl_triangles())

    def _object_map(self, i, s):
        """(side, texture): the sphere's irradiance over its normals, with a
        one-texel border (bordered) for the GPU's bilinear read. No larger
        than a probe cell: its probes blended at its centre (object_map,
        the probes' map size); larger: the per-point sum at each of
        SURFACE_MAP squared normals' points (sphere_map), its probes masked
        by what its centre sees; in the window MOVING_MAP squared while it
        moves (the lamps' shadows from its centre), the full map the first
        frame it stands still. Each map
        texture lives as long as the viewer, rewritten when the object
        moves (a texture made and freed each frame stalled llvmpipe). The
        map is made on the CPU: a GPU pass into a texture the same frame
        reads made llvmpipe stop and finish it (8 ms a frame while an
        object moved, against 2 ms here)."""
        import moderngl
        from baker.probes.sample import object_map, sphere_map
        kind = "blended" if s.radius <= self.grid.spacing else "surface"
        key = (tuple(s.center), float(s.radius))
        moving = False
        if kind == "blended":
            size = self.grid.irradiance.shape[1]
        else:
            last = self.shown.get((kind, i))
            moving = self.interactive and last is not None and last[1] != key
            size = MOVING_MAP if moving else SURFACE_MAP
        if (kind, i, size) not in self.maps:
            tex = self.ctx.texture((size + 2, size + 2), 3, dtype="f4")
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
            self.maps[(kind, i, size)] = [tex, None]
        tex, held = self.maps[(kind, i, size)]
        if held != key:
            if kind == "blended":
                m = object_map(self.grid, s.center, self.bvh, self.lights)
            else:
                m = sphere_map(self.grid, s.center, s.radius, probe_seen(self.grid, s.center, s.radius, self.bvh),
                               size, self.lights, coarse=moving)
            tex.write(bordered(m).tobytes())
            self.maps[(kind, i, size)][1] = key
        self.shown[(kind, i)] = (size, key)
        return size, tex

    def release(self):
        for prog, vao in self.programs.values():
            vao.release()
            prog.release()
        for obj in (self.vbo, *(m[0] for m in self.maps.values())):
            obj.release()


class DynamicMeshes:
    """Draws the bake's dynamic meshes lit by its probes into the bound
    framebuffer: each vertex's irradiance is points_irradiance at the
    vertex and its normal where the mesh stands, made on the CPU when it
    moves (2,000 vertices take 0.6 ms), over the probes valid and seen
    from the centre of its bounds (probe_seen: a mesh beside a wall lit by
    its own side); the shader interpolates it over the triangles."""

    def __init__(self, ctx, bake, prepared=None, interactive=False):
        from baker.errors import VoxgiError
        from baker.probes.sample import probe_lights
        from baker.scene.prepared import prepare
        from .renderer import material_texture
        if bake.probes is None:
            raise VoxgiError("the bake holds no irradiance probes to light its dynamic meshes")
        prepared = prepared if prepared is not None else prepare(bake.scene)
        self.ctx = ctx
        self.grid = bake.probes
        self.materials = bake.scene.materials
        self.bvh = prepared.bvh.arrays
        self.lights = probe_lights(self.grid, prepared, OBJECT_LAMP_RAYS)
        self.interactive = interactive   # the window: the lamps' shadows from the mesh's centre while it moves
        self.meshes = []   # per mesh: dict of its buffers, groups and the offset its irradiance is for
        self.textures = {}
        self.programs = {}
        for d in bake.scene.dynamic:
            order = np.argsort(d.material_ids, kind="stable")
            tri = np.ascontiguousarray(d.triangles[order], np.uint32)
            mids = d.material_ids[order]
            starts = np.flatnonzero(np.r_[True, mids[1:] != mids[:-1]])
            groups = [(int(mids[a]), 3 * int(a), 3 * int(b - a)) for a, b in zip(starts, np.r_[starts[1:], len(mids)])]
            uv = d.uvs if d.uvs is not None else np.zeros((len(d.vertices), 2), np.float32)
            geo = np.concatenate([d.vertices, uv], axis=1).astype(np.float32)
            r = float(np.linalg.norm(d.vertices.max(axis=0).astype(np.float64) - d.vertices.min(axis=0)) / 2)
            self.meshes.append({"mesh": d, "geo": ctx.buffer(geo.tobytes()), "index": ctx.buffer(tri.tobytes()),
                                "irr": ctx.buffer(reserve=len(d.vertices) * 12), "groups": groups, "held": None, "coarse": False,
                                "center": mesh_center(d), "radius": r, "textured": d.uvs is not None, "vaos": {}})
            for mi in set(int(m) for m in mids):
                m = self.materials[mi]
                if m.texture is not None and d.uvs is not None and mi not in self.textures:
                    self.textures[mi] = material_texture(ctx, m)

    def _program(self, tonemap, textured):
        key = (bool(tonemap), bool(textured))
        if key not in self.programs:
            from .context import build_program
            self.programs[key] = build_program(self.ctx, "probe_mesh.vert", "probe_mesh.frag",
                                               {"TONEMAP": int(tonemap), "TEXTURED": int(textured)})
        return self.programs[key]

    def _vao(self, entry, prog, key):
        if key not in entry["vaos"]:
            geo = (entry["geo"], "3f 2f", "in_position", "in_uv") if "in_uv" in prog else \
                (entry["geo"], "3f 8x", "in_position")   # (an untextured program reads no UVs: skip their bytes)
            entry["vaos"][key] = self.ctx.vertex_array(prog, [geo, (entry["irr"], "3f", "in_irradiance")],
                                                       index_buffer=entry["index"], index_element_size=4)
        return entry["vaos"][key]

    def irradiance(self, i, offset, coarse=False) -> np.ndarray:
        """(nv, 3) float32: mesh i's vertices' irradiance moved by offset;
        coarse: the lamps' shadows from the centre of its bounds, not from
        each vertex."""
        from baker.probes.sample import points_irradiance
        e = self.meshes[i]
        off = np.asarray(offset, np.float64)
        seen = probe_seen(self.grid, e["center"] + off, e["radius"], self.bvh)
        return points_irradiance(self.grid, e["mesh"].vertices.astype(np.float64) + off, e["mesh"].normals, seen,
                                 self.lights, e["center"] + off if coarse else None)

    def update(self, i, offset) -> tuple:
        """Mesh i's irradiance buffer for `offset` (3,), remade where it
        moved: in the window, with the lamps' shadows from its centre
        while it moves (coarse) and from each vertex the first frame it
        stands still. The offset as a tuple of floats."""
        e = self.meshes[i]
        off = tuple(float(v) for v in offset)
        moving = self.interactive and e["held"] is not None and e["held"] != off
        if e["held"] != off or (e["coarse"] and not moving):
            e["irr"].write(np.ascontiguousarray(self.irradiance(i, off, moving), np.float32).tobytes())
            e["held"], e["coarse"] = off, moving
        return off

    def draw(self, vp, offsets, tonemap=True, exposure=1.0):
        """Every dynamic mesh, mesh i moved by offsets[i] (3,)."""
        import moderngl
        self.ctx.disable(moderngl.CULL_FACE)   # the file's two-sidedness is not kept for them: show both faces
        try:
            for i, e in enumerate(self.meshes):
                off = self.update(i, offsets[i])
                for mi, first, count in e["groups"]:
                    m = self.materials[mi]
                    tex = self.textures.get(mi)
                    prog = self._program(tonemap, tex is not None)
                    prog["u_view_proj"].write(vp.T.astype(np.float32).tobytes())
                    for name, value in (("u_offset", off), ("u_albedo", tuple(float(v) for v in m.albedo)),
                                        ("u_emission", tuple(float(v) for v in m.emission)),
                                        ("u_alpha", float(m.alpha)),
                                        ("u_cutoff", float(m.alpha_cutoff) if m.masked else -1.0),
                                        ("u_exposure", float(exposure)), ("u_texture", 5)):
                        if name in prog:
                            prog[name].value = value
                    if tex is not None:
                        tex.use(5)
                    self._vao(e, prog, (bool(tonemap), tex is not None)).render(moderngl.TRIANGLES, vertices=count,
                                                                                 first=first)
        finally:
            self.ctx.enable(moderngl.CULL_FACE)

    def release(self):
        for e in self.meshes:
            for vao in e["vaos"].values():
                vao.release()
            for key in ("geo", "index", "irr"):
                e[key].release()
        for prog in self.programs.values():
            prog.release()
        for tex in self.textures.values():
            tex.release()


PROBE_SIZE = 0.12   # the probe view's spheres' radius, in probe spacings


class ProbeGridView:
    """The probe view: every probe of a bake as a small sphere where it
    stands, shaded by its SH (a white diffuse sphere's radiance; invalid
    probes flat red), drawn into the bound framebuffer with one instanced
    call."""

    def __init__(self, ctx, bake):
        from baker.errors import VoxgiError
        if bake.probes is None:
            raise VoxgiError("the bake holds no irradiance probes: bake it again without --no-probes")
        from .context import build_program
        self.ctx = ctx
        self.grid = g = bake.probes
        table = np.zeros((g.count, 10, 3), np.float32)
        table[:, :9] = g.sh
        table[:, 9, 0] = g.valid
        packed = _packed(table, 3)
        if len(packed) > 16384:
            raise VoxgiError(f"{g.count:,} probes are more than the viewer's textures hold")
        self.sh = ctx.texture((WIDTH, len(packed)), 3, packed.tobytes(), dtype="f4")
        import moderngl
        self.sh.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.vbo = ctx.buffer(sphere_mesh(2).tobytes())
        self.programs = {}
        self._build = build_program

    def draw(self, vp, tonemap=True, exposure=1.0):
        key = bool(tonemap)
        if key not in self.programs:
            prog = self._build(self.ctx, "probe_grid.vert", "probe_grid.frag", {"TONEMAP": int(tonemap)})
            self.programs[key] = (prog, self.ctx.vertex_array(prog, [(self.vbo, "3f", "in_position")]))
        prog, vao = self.programs[key]
        g = self.grid
        prog["u_view_proj"].write(vp.T.astype(np.float32).tobytes())
        for name, value in (("u_origin", tuple(float(v) for v in g.origin)), ("u_spacing", float(g.spacing)),
                            ("u_dims", tuple(int(v) for v in g.dims)), ("u_radius", PROBE_SIZE * float(g.spacing)),
                            ("u_sh", 7), ("u_exposure", float(exposure))):
            if name in prog:
                prog[name].value = value
        self.sh.use(7)
        vao.render(moderngl_triangles(), instances=g.count)

    def release(self):
        for prog, vao in self.programs.values():
            vao.release()
            prog.release()
        self.sh.release()
        self.vbo.release()
