"""Stage 4b, lights: virtual point lights from the voxel solution and the
scene's emitters (vpl.py), the light tree over them (lighttree.py) and
lightcuts at shading points (lightcuts.py); docs/design.md sections 6-7."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..config import LightcutsConfig
from .lamps import LampArrays, lamp_groups
from .lightcuts import SkyCells, TreeArrays, VPLArrays, brute_force, lightcut, node_patches
from .shade import shade_points
from .lighttree import LightTree, build_tree
from .ordered import ordered_vpls
from ..scene.surfaces import SKY_HEMISPHERE
from .vpl import KIND_AREA, KIND_DIRECTIONAL, VPLs, concat, direct_vpls, indirect_vpls, make_vpls, sky_vpls


@dataclass(frozen=True)
class Lights:
    """The VPLs and their tree (None when there are none). sky: the
    directions (K, 3) along which shading points see the sky, by a
    visibility ray each (lightcuts.sky_light); then the tree holds only
    the VPLs before the sky's (vpls.kind: KIND_AREA), and the sky's VPLs
    are there for the viewer's preview and the bake file. None: the sky's
    directions, if any, are VPLs of the tree like any other."""
    vpls: VPLs
    tree: LightTree | None
    sky: np.ndarray | None = None

    @property
    def points(self) -> int:
        """How many VPLs (from the first) the cuts and the brute force sum."""
        return len(self.vpls) if self.sky is None else int(np.sum(self.vpls.kind != KIND_DIRECTIONAL))


def build_lights(prepared, solution, config: LightcutsConfig, on_surface=True, tree=True) -> Lights:
    """The VPLs and their tree for a Prepared scene and its voxel Solution;
    the sky is shaded along its own VPLs' directions (Lights.sky): a cut
    over a partly hidden sky refines to nearly every direction anyway, at
    the cost of a tree walk and a bound per ray. on_surface: voxel VPLs
    that lie just under their curved surface move onto it through the BVH
    (vpl.on_surface). tree=False: no tree (for split_lights, which
    builds its parts' own)."""
    bvh = prepared.bvh if on_surface else None
    vpls = make_vpls(prepared.scene, solution, prepared.surfaces, config.direct_vpls, config.sky_vpls, config.seed,
                     bvh)
    sky = vpls.kind == KIND_DIRECTIONAL
    m = int(np.sum(~sky))
    if np.any(sky[:m]):
        raise AssertionError("make_vpls puts the sky's directions last")
    t = build_tree(vpls.subset(m), config.seed) if m and tree else None
    return Lights(vpls, t, np.ascontiguousarray(vpls.normal[m:], np.float64))


def split_lights(lights: Lights, seed=0, tree=True) -> tuple[Lights, Lights | None]:
    """(sharp, smooth), each with its own tree: the emitters' VPLs alone,
    and the voxels' VPLs with the sky's directions (None: neither). The
    smooth part varies slowly over a surface (bounced light, and the sky's,
    whose every shadow is an ambient occlusion's penumbra), so a bake
    shades it on a sparse lattice (lightmap.values.sparse_bounced). A
    point's irradiance is the sum of the two; shade the smooth part with
    exact=False (no punctual lights: they belong to the sharp part). Where
    lights.sky is None (the sky's directions are VPLs of its tree), the
    sky stays with the sharp part. tree=False: the smooth part's voxel
    VPLs get no tree (its cuts then see the sky alone: a bake that gathers
    the bounced light from the voxels, solve/gather.py)."""
    v = lights.vpls
    if lights.sky is None:
        direct = v.select(~v.indirect)
        d = Lights(direct, build_tree(direct, seed) if len(direct) else None, None)
        sky = None
    else:
        direct = v.select(~v.indirect & (v.kind != KIND_DIRECTIONAL))
        d = Lights(direct, build_tree(direct, seed) if len(direct) else None, None)
        sky = lights.sky if len(lights.sky) else None
    if not v.indirect.any() and sky is None:
        return d, None
    bounced = v.select(v.indirect)
    return d, Lights(bounced, build_tree(bounced, seed) if len(bounced) and tree else None,
                     np.zeros((0, 3)) if sky is None else sky)


def irradiance(lights: Lights, bvh, surfaces, points, normals, valid=None, offset=1e-4, epsilon=0.02, cap=1000,
               brute=False, near=True, exact=True, floor=None, adaptive_sky=True, analytic=False):
    """H (N, 3) float64 at points with unit normals (the side that
    receives), plus cut sizes and shadow rays per point. near: area VPLs
    near a point are integrated over their patch (lightcuts.vpl_g; off:
    the bounded point form throughout, as the viewer's GPU preview).
    exact: the scene's punctual lights are included (off: the VPLs and
    the sky's directions alone); floor (N,): the luminance of irradiance
    each point gets from elsewhere, which the cuts' error is bounded
    against besides their own (split_lights); adaptive_sky: the sky
    by a ray per cell of its directions where they agree
    (lightcuts.sky_light; off: a ray along every direction); analytic:
    where the VPLs are the area emitters' alone, none of them textured and
    at most ANALYTIC_EMITTERS triangles, their light is taken from the
    emitters themselves, lamp by lamp (lamps.lamps_light: each lamp's
    exact unoccluded light times its visibility by rays over its solid
    angle), exact wherever nothing blocks them."""
    points = np.ascontiguousarray(points, np.float64)
    normals = np.ascontiguousarray(normals, np.float64)
    valid = np.ones(len(points), bool) if valid is None else np.ascontiguousarray(valid, bool)
    v, t = lights.vpls, lights.tree
    sky = np.zeros((0, 3)) if lights.sky is None else lights.sky
    if lights.sky is not None:
        v = v.subset(lights.points)
    if t is None:
        t = LightTree(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)), np.ones(1), np.zeros((1, 3)),
                      np.zeros(1), np.zeros(1, np.int64), np.full(1, -1, np.int64), np.zeros(1, np.int8))
    if not exact:
        surfaces = replace(surfaces, arrays=surfaces.arrays._replace(light_kind=np.zeros(0, np.int32)))
    a = surfaces.arrays
    cells = sky_cells(sky, a.sky_up, a.sky_mode == SKY_HEMISPHERE, SKY_CELL if adaptive_sky else 1)
    floor = np.zeros(len(points)) if floor is None else np.ascontiguousarray(floor, np.float64)
    patch = np.where(v.indirect & (v.kind == KIND_AREA), v.area, 0.0) if near else np.zeros(len(v))
    analytic = bool(analytic and not brute and len(v) and analytic_emitters(surfaces)
                    and not v.indirect.any() and (v.kind == KIND_AREA).all())
    tree = tree_arrays(t, node_patches(t.rep, t.right, patch) if len(v) else np.zeros(len(t)))
    lamps = lamp_groups(a) if analytic else LampArrays(np.zeros(1, np.int64), np.zeros(0, np.int64))
    return shade_points(bvh.arrays, surfaces.arrays, tree, VPLArrays(v.kind, v.position, v.normal, v.area, v.power,
                                                                     patch),
                        cells, points, normals, valid, floor, float(offset), float(epsilon), int(cap), bool(brute),
                        lamps)


ANALYTIC_EMITTERS = 2048   # emitter triangles summed exactly at each point (lightcuts.emitters_unoccluded)


def analytic_emitters(surfaces) -> bool:
    """Whether the emitters' unoccluded light can be summed exactly at
    each point: at most ANALYTIC_EMITTERS triangles, none with an emissive
    texture (the sum takes each triangle's mean radiance)."""
    a = surfaces.arrays
    e = a.emitters
    return 0 < len(e) <= ANALYTIC_EMITTERS and not (a.emit_offset[a.tri_material[e]] >= 0).any()


SKY_CELL = 8     # the sky's directions per cell of the adaptive sky (lightcuts.sky_light)
NEIGHBOURS = 8   # a sky cell's nearest cells that count as its neighbours (about its Voronoi neighbours)


def sky_cells(dirs, up, hemisphere, per_cell=SKY_CELL) -> SkyCells:
    """The sky's directions (K, 3) grouped into C = K / per_cell compact
    cells: C centres stratified over the sky's domain (a Fibonacci lattice
    on the upper hemisphere about `up`, or the sphere), each direction in
    the cell of its nearest centre; a cell's neighbours are the cells whose
    centres are among each other's NEIGHBOURS nearest; its representative
    its direction nearest its centre. per_cell 1 or C < 4: every direction
    its own cell, without neighbours."""
    dirs = np.ascontiguousarray(dirs, np.float64)
    k = len(dirs)
    n_cells = k // max(int(per_cell), 1)
    if per_cell <= 1 or n_cells < 4:
        return SkyCells(dirs, np.arange(k + 1, dtype=np.int64), np.arange(k, dtype=np.int64),
                        np.full((k, 1), -1, np.int64))
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    t = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 0.0, 1.0])
    t /= np.linalg.norm(t)
    b = np.cross(up, t)
    i = np.arange(n_cells) + 0.5
    z = 1.0 - i / n_cells if hemisphere else 1.0 - 2.0 * i / n_cells   # uniform in solid angle
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    centre = (r * np.cos(phi))[:, None] * t + (r * np.sin(phi))[:, None] * b + z[:, None] * up
    cell = np.argmax(dirs @ centre.T, axis=1)
    order = np.lexsort((np.arange(k), cell))
    counts = np.bincount(cell, minlength=n_cells)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    sorted_dirs = dirs[order]
    rep = np.full(n_cells, -1, np.int64)
    for c in np.nonzero(counts)[0]:
        rep[c] = start[c] + int(np.argmax(sorted_dirs[start[c]:start[c + 1]] @ centre[c]))
    near = np.argsort(-(centre @ centre.T), axis=1, kind="stable")[:, 1:NEIGHBOURS + 1]
    adj = np.zeros((n_cells, n_cells), bool)
    adj[np.repeat(np.arange(n_cells), near.shape[1]), near.ravel()] = True
    adj |= adj.T
    adj &= (counts > 0)[None, :]
    width = max(1, int(adj.sum(axis=1).max()))
    nbr = np.full((n_cells, width), -1, np.int64)
    for c in range(n_cells):
        o = np.nonzero(adj[c])[0]
        nbr[c, :len(o)] = o
    return SkyCells(sorted_dirs, start, rep, nbr)


def tree_arrays(tree: LightTree, patch) -> TreeArrays:
    """The kernels' view of the tree: its node fields as strided views into
    one 128-byte record per node (lo, hi, axis, cos, power, lum, then rep
    and right as int64), so a cut reads a node from two adjacent cache
    lines, not from eight arrays (the same cuts, bit for bit); patch: the
    largest VPL patch under each node (lightcuts.node_patches)."""
    m = len(tree)
    rec = np.empty((m, 16))
    ints = rec.view(np.int64)
    rec[:, 0:3], rec[:, 3:6], rec[:, 6:9], rec[:, 9] = tree.lo, tree.hi, tree.axis, tree.cos
    rec[:, 10:13], rec[:, 13] = tree.power, tree.lum
    ints[:, 14], ints[:, 15] = tree.rep, tree.right
    return TreeArrays(rec[:, 0:3], rec[:, 3:6], rec[:, 6:9], rec[:, 9], rec[:, 10:13], rec[:, 13], ints[:, 14],
                      ints[:, 15], tree.kind, np.ascontiguousarray(patch, np.float64))


__all__ = ["KIND_AREA", "KIND_DIRECTIONAL", "LightTree", "Lights", "VPLs",
           "SkyCells", "brute_force", "build_lights", "build_tree", "concat", "direct_vpls", "indirect_vpls",
           "irradiance", "lightcut", "make_vpls", "ordered_vpls", "sky_cells", "sky_vpls", "split_lights"]
