"""The BVH as a Python object: build once per scene, pass `.arrays` to kernels."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kernels.bvh import LEAF_MAX, build_bvh, reorder_triangles
from .kernels.traverse import any_hit_batch, closest_hit_batch


@dataclass(frozen=True)
class BVH:
    lo: np.ndarray          # (nn, 3) float64 node bounds
    hi: np.ndarray
    right: np.ndarray       # (nn,) int32 right child (left child is node + 1)
    first: np.ndarray       # (nn,) int32 first triangle of a leaf
    count: np.ndarray       # (nn,) int32 triangles in a leaf (0: inner node)
    v0: np.ndarray          # (nt, 3) float64 triangle corners in BVH order
    v1: np.ndarray
    v2: np.ndarray
    tri_index: np.ndarray   # (nt,) int32 BVH order -> scene triangle

    @property
    def arrays(self):
        return (self.lo, self.hi, self.right, self.first, self.count, self.v0, self.v1, self.v2, self.tri_index)

    @property
    def node_count(self) -> int:
        return len(self.right)

    def closest(self, origins, dirs, tmin=0.0, tmax=np.inf):
        """Batch closest hit: (t, triangle, u, v); triangle -1 and t inf on a miss."""
        o, d, tm = _rays(origins, dirs, tmax)
        return closest_hit_batch(self.arrays, o, d, float(tmin), tm)

    def occluded(self, origins, dirs, tmin=0.0, tmax=np.inf):
        """Batch any hit: (n,) bool."""
        o, d, tm = _rays(origins, dirs, tmax)
        return any_hit_batch(self.arrays, o, d, float(tmin), tm)


def _rays(origins, dirs, tmax):
    o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
    d = np.ascontiguousarray(dirs, np.float64).reshape(-1, 3)
    tm = np.broadcast_to(np.asarray(tmax, np.float64), (len(o),)).copy()
    return o, d, tm


def build(corners: np.ndarray, leaf_max: int = LEAF_MAX) -> BVH:
    """BVH over triangles given as corners (nt, 3, 3). Node boxes are padded
    by a relative 1e-9 of the scene extent so that rays lying in a box face
    are not lost to rounding."""
    corners = np.ascontiguousarray(corners, np.float64)
    lo, hi, right, first, count, order = build_bvh(corners, leaf_max)
    scale = float(np.abs(corners).max()) if corners.size else 1.0
    pad = 1e-9 * max(scale, 1e-30)
    v0, v1, v2 = reorder_triangles(corners, order)
    return BVH(lo - pad, hi + pad, right, first, count, v0, v1, v2, order.astype(np.int32))


def build_scene_bvh(scene) -> BVH:
    return build(scene.triangle_corners())
