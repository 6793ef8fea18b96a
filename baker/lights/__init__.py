"""Stage 4b, lights: virtual point lights from the voxel solution and the
scene's emitters (vpl.py), the light tree over them (lighttree.py) and
lightcuts at shading points (lightcuts.py); docs/design.md sections 6-7."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .lightcuts import brute_force, lightcut, node_patches, shade_points
from .lighttree import LightTree, build_tree
from .ordered import ordered_vpls
from .vpl import KIND_AREA, KIND_DIRECTIONAL, VPLs, concat, direct_vpls, indirect_vpls, make_vpls, sky_vpls


@dataclass(frozen=True)
class LightcutsConfig:
    """direct_vpls: points on the area emitters; sky_vpls: directions of
    the sky; epsilon: the cut's relative error bound; cap: the largest cut;
    seed."""
    direct_vpls: int = 32_768
    sky_vpls: int = 1024
    epsilon: float = 0.02
    cap: int = 1000
    seed: int = 0

    def __post_init__(self):
        if self.direct_vpls < 0 or self.sky_vpls < 0:
            raise ConfigError("VPL counts must be >= 0")
        if not 0 <= self.epsilon < 1:
            raise ConfigError(f"epsilon must lie in [0, 1) (got {self.epsilon})")
        if self.cap < 1:
            raise ConfigError(f"the cut cap must be >= 1 (got {self.cap})")


LIGHTCUTS_PRESETS = {
    "preview": LightcutsConfig(direct_vpls=4096, sky_vpls=256, epsilon=0.05, cap=300),
    "default": LightcutsConfig(direct_vpls=32_768, sky_vpls=1024, epsilon=0.02, cap=1000),
    "high": LightcutsConfig(direct_vpls=131_072, sky_vpls=4096, epsilon=0.01, cap=2000),
}


def lightcuts_config(preset="default", **overrides) -> LightcutsConfig:
    from dataclasses import replace
    if preset not in LIGHTCUTS_PRESETS:
        raise ConfigError(f"unknown preset {preset!r}; choose from {', '.join(LIGHTCUTS_PRESETS)}")
    return replace(LIGHTCUTS_PRESETS[preset], **{k: v for k, v in overrides.items() if v is not None})


@dataclass(frozen=True)
class Lights:
    """The VPLs and their tree (None when there are none)."""
    vpls: VPLs
    tree: LightTree | None


def build_lights(scene, solution, surfaces, config: LightcutsConfig, bvh=None) -> Lights:
    """The VPLs and their tree. bvh: the scene's BVH (puts voxel VPLs that
    lie just under their curved surface onto it: vpl.on_surface)."""
    vpls = make_vpls(scene, solution, surfaces, config.direct_vpls, config.sky_vpls, config.seed, bvh)
    return Lights(vpls, build_tree(vpls, config.seed) if len(vpls) else None)


def irradiance(lights: Lights, bvh, surfaces, points, normals, valid=None, offset=1e-4, epsilon=0.02, cap=1000,
               brute=False, near=True):
    """H (N, 3) float64 at points with unit normals (the side that
    receives), plus cut sizes and shadow rays per point. near: area VPLs
    near a point are integrated over their patch (lightcuts.vpl_g; off:
    the bounded point form throughout, as the viewer's GPU preview)."""
    points = np.ascontiguousarray(points, np.float64)
    normals = np.ascontiguousarray(normals, np.float64)
    valid = np.ones(len(points), bool) if valid is None else np.ascontiguousarray(valid, bool)
    v, t = lights.vpls, lights.tree
    if t is None:
        t = LightTree(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)), np.ones(1), np.zeros((1, 3)),
                      np.zeros(1), np.zeros(1, np.int64), np.full(1, -1, np.int64), np.zeros(1, np.int8))
    lo, hi, axis, cos, power, lum, rep, right = packed(t)
    patch = np.where(v.indirect & (v.kind == KIND_AREA), v.area, 0.0) if near else np.zeros(len(v))
    return shade_points(bvh.arrays, surfaces.arrays, lo, hi, axis, cos, power, lum, rep, right, t.kind, v.kind,
                        v.position, v.normal, v.area, v.power, points, normals, valid, float(offset), float(epsilon),
                        int(cap), bool(brute), patch,
                        node_patches(t.rep, t.right, patch) if len(v) else np.zeros(len(t)))


def packed(tree: LightTree):
    """The tree's node fields as strided views into one 128-byte record per
    node (lo, hi, axis, cos, power, lum, then rep and right as int64): a
    cut reads a node from two adjacent cache lines, not from eight arrays
    (the same cuts, bit for bit; 15-20% faster on the Cornell box's
    lightmap texels)."""
    m = len(tree)
    rec = np.empty((m, 16))
    ints = rec.view(np.int64)
    rec[:, 0:3], rec[:, 3:6], rec[:, 6:9], rec[:, 9] = tree.lo, tree.hi, tree.axis, tree.cos
    rec[:, 10:13], rec[:, 13] = tree.power, tree.lum
    ints[:, 14], ints[:, 15] = tree.rep, tree.right
    return (rec[:, 0:3], rec[:, 3:6], rec[:, 6:9], rec[:, 9], rec[:, 10:13], rec[:, 13], ints[:, 14],
            ints[:, 15])


__all__ = ["KIND_AREA", "KIND_DIRECTIONAL", "LIGHTCUTS_PRESETS", "LightTree", "Lights", "LightcutsConfig", "VPLs",
           "brute_force", "build_lights", "build_tree", "concat", "direct_vpls", "indirect_vpls", "irradiance",
           "lightcut", "lightcuts_config", "make_vpls", "ordered_vpls", "sky_vpls"]
