"""Stage 4b, lights: virtual point lights from the voxel solution and the
scene's emitters (vpl.py), the light tree over them (lighttree.py) and
lightcuts at shading points (lightcuts.py); docs/design.md sections 6-7."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..config import LightcutsConfig
from .lightcuts import TreeArrays, VPLArrays, brute_force, lightcut, node_patches, shade_points
from .lighttree import LightTree, build_tree
from .ordered import ordered_vpls
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


def build_lights(prepared, solution, config: LightcutsConfig, on_surface=True) -> Lights:
    """The VPLs and their tree for a Prepared scene and its voxel Solution;
    the sky is shaded along its own VPLs' directions (Lights.sky): a cut
    over a partly hidden sky refines to nearly every direction anyway, at
    the cost of a tree walk and a bound per ray. on_surface: voxel VPLs
    that lie just under their curved surface move onto it through the BVH
    (vpl.on_surface)."""
    bvh = prepared.bvh if on_surface else None
    vpls = make_vpls(prepared.scene, solution, prepared.surfaces, config.direct_vpls, config.sky_vpls, config.seed,
                     bvh)
    sky = vpls.kind == KIND_DIRECTIONAL
    m = int(np.sum(~sky))
    if np.any(sky[:m]):
        raise AssertionError("make_vpls puts the sky's directions last")
    tree = build_tree(vpls.subset(m), config.seed) if m else None
    return Lights(vpls, tree, np.ascontiguousarray(vpls.normal[m:], np.float64))


def split_lights(lights: Lights, seed=0) -> tuple[Lights, Lights | None]:
    """(direct, bounced): the emitters' VPLs and the sky, and the voxels'
    VPLs alone (None: there are none), each with its own tree. A point's
    irradiance is the sum of the two; shade the bounced part with
    exact=False (no punctual lights: they belong to the direct part)."""
    v = lights.vpls
    direct = v.select(~v.indirect)
    m = int(np.sum(direct.kind != KIND_DIRECTIONAL)) if lights.sky is not None else len(direct)
    d = Lights(direct, build_tree(direct.subset(m), seed) if m else None, lights.sky)
    if not v.indirect.any():
        return d, None
    bounced = v.select(v.indirect)
    return d, Lights(bounced, build_tree(bounced, seed), None)


def irradiance(lights: Lights, bvh, surfaces, points, normals, valid=None, offset=1e-4, epsilon=0.02, cap=1000,
               brute=False, near=True, exact=True, floor=None):
    """H (N, 3) float64 at points with unit normals (the side that
    receives), plus cut sizes and shadow rays per point. near: area VPLs
    near a point are integrated over their patch (lightcuts.vpl_g; off:
    the bounded point form throughout, as the viewer's GPU preview).
    exact: the scene's punctual lights are included (off: the VPLs and
    the sky's directions alone); floor (N,): the luminance of irradiance
    each point gets from elsewhere, which the cuts' error is bounded
    against besides their own (split_lights)."""
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
    floor = np.zeros(len(points)) if floor is None else np.ascontiguousarray(floor, np.float64)
    patch = np.where(v.indirect & (v.kind == KIND_AREA), v.area, 0.0) if near else np.zeros(len(v))
    tree = tree_arrays(t, node_patches(t.rep, t.right, patch) if len(v) else np.zeros(len(t)))
    return shade_points(bvh.arrays, surfaces.arrays, tree, VPLArrays(v.kind, v.position, v.normal, v.area, v.power,
                                                                     patch),
                        sky, points, normals, valid, floor, float(offset), float(epsilon), int(cap), bool(brute))


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
           "brute_force", "build_lights", "build_tree", "concat", "direct_vpls", "indirect_vpls", "irradiance",
           "lightcut", "make_vpls", "ordered_vpls", "sky_vpls", "split_lights"]
