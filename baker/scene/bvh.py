"""The scene's BVH as a Python object: build once, pass `.arrays` to kernels."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels.bvh import (LEAF_MAX, PASS_GLASS, PASS_MASK, PASS_OPAQUE, STACK_SIZE, WIDE_CHILD, WIDE_COUNT, WIDE_HI,
                           WIDE_LO, WIDE_RECORD, BVHArrays, build_bvh, WIDTH, collapse_wide, pack_nodes,
                           reorder_triangles)
from ..kernels.traverse import any_hit_batch, closest_hit_batch, transmittance_batch


@dataclass(frozen=True)
class BVH:
    child_box: np.ndarray   # (nn, 12) float32 boxes of the two children of each inner node
    root_box: np.ndarray    # (6,) float64
    right: np.ndarray       # (nn,) int32 right child (left child is node + 1)
    first: np.ndarray       # (nn,) int32 first triangle of a leaf
    count: np.ndarray       # (nn,) int32 triangles in a leaf (0: inner node)
    tris: np.ndarray        # (nt, 9) float64 corners in BVH order (float32 values)
    tri_index: np.ndarray   # (nt,) int32 BVH order -> scene triangle
    depth: int = 0          # the deepest node's level (root 0)
    wide: np.ndarray = None  # (nw, WIDE_RECORD) float32: the same tree 8-wide, what the traversal reads
    passes: tuple = None    # what rays pass: the BVHArrays fields from tri_pass on (ray_passes)

    @property
    def arrays(self) -> BVHArrays:
        return BVHArrays(self.wide, self.wide.view(np.int32), self.root_box, self.tris, self.tri_index,
                         *self.passes)

    @property
    def passes_light(self) -> bool:
        """Does any triangle let rays through (masked or glass)?"""
        return bool(np.any(self.passes[0] != PASS_OPAQUE))

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

    def transmitted(self, origins, dirs, tmin=0.0, tmax=np.inf):
        """Batch transmittance: (n, 3) float64 (kernels/traverse.transmittance)."""
        o, d, tm = _rays(origins, dirs, tmax)
        return transmittance_batch(self.arrays, o, d, float(tmin), tm)


def _rays(origins, dirs, tmax):
    o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
    d = np.ascontiguousarray(dirs, np.float64).reshape(-1, 3)
    tm = np.broadcast_to(np.asarray(tmax, np.float64), (len(o),)).copy()
    return o, d, tm


def _outward32(box):
    """float64 boxes (..., 6 or 12) -> float32 rounded outward (lo down, hi up)."""
    b32 = box.astype(np.float32)
    shape = b32.shape
    b = box.reshape(-1, 6)
    f = b32.reshape(-1, 6)
    lo_up = f[:, :3] > b[:, :3]
    f[:, :3][lo_up] = np.nextafter(f[:, :3][lo_up], np.float32(-np.inf))
    hi_dn = f[:, 3:] < b[:, 3:]
    f[:, 3:][hi_dn] = np.nextafter(f[:, 3:][hi_dn], np.float32(np.inf))
    return f.reshape(shape)


def build(corners: np.ndarray, leaf_max: int = LEAF_MAX) -> BVH:
    """BVH over triangles given as corners (nt, 3, 3) (binned SAH).

    Corners are rounded to float32 (exact for scene vertices, float32
    already) and stored as float64: the intersection test computes in
    float64, and converting nine numbers in every triangle test showed in
    the path tracer's time.
    Node boxes are padded by a relative 1e-9 of the scene extent and rounded
    outward to float32 so rounding never loses a hit."""
    corners = np.ascontiguousarray(np.asarray(corners, np.float32), np.float64)
    lo, hi, right, first, count, order, depth = build_bvh(corners, leaf_max)
    if (WIDTH - 1) * (depth + 1) > STACK_SIZE:  # the build bounds it (kernels/bvh.py): this would be a bug
        raise RuntimeError(f"BVH depth {depth} exceeds the traversal stack ({STACK_SIZE} entries, "
                           f"{WIDTH - 1} a level)")
    scale = float(np.abs(corners).max()) if corners.size else 1.0
    pad = 1e-9 * max(scale, 1e-30)
    lo, hi = lo - pad, hi + pad
    child = pack_nodes(lo, hi, right, count)
    root = np.concatenate([lo[0], hi[0]]).astype(np.float64)
    return BVH(_outward32(child), root, right, first, count, reorder_triangles(corners, order),
               order.astype(np.int32), int(depth), _wide(lo, hi, right, first, count), opaque(len(order)))


def opaque(nt: int) -> tuple:
    """The pass tables of triangles that are all opaque."""
    return (np.zeros(nt, np.int8), np.zeros(nt, np.int32), np.zeros((1, 6)), np.full(1, -1, np.int64),
            np.zeros((1, 2), np.int64), np.ones(1), np.zeros(1), np.zeros(1, np.float32), np.zeros((1, 3)))


def ray_passes(scene, tri_index) -> tuple:
    """The pass tables (BVHArrays' tri_pass .. glass_tint) of `scene`'s
    triangles in BVH order (tri_index: BVH order -> scene triangle):
    masked materials are alpha-tested at each hit (their alpha texture,
    nearest texel, wrapped, as the albedo), thin glass tints what passes by
    t x its base colour factor (a glass's texture does not tint)."""
    mats = scene.materials
    nm = max(len(mats), 1)
    mat = scene.material_ids[tri_index].astype(np.int32)
    masked = np.array([m.masked for m in mats] or [False])
    glass = np.array([m.transmission > 0 for m in mats] or [False])
    kind = np.where(masked[mat], PASS_MASK, np.where(glass[mat], PASS_GLASS, PASS_OPAQUE)).astype(np.int8)
    offset, size = np.full(nm, -1, np.int64), np.zeros((nm, 2), np.int64)
    alpha, cutoff = np.ones(nm), np.zeros(nm)
    tint = np.zeros((nm, 3))
    chunks, off = [], 0
    for i, m in enumerate(mats):
        tint[i] = m.transmission * np.asarray(m.albedo, np.float64)
        if not m.masked:
            continue
        alpha[i], cutoff[i] = m.alpha, m.alpha_cutoff
        if m.opacity is not None and scene.uvs is not None:
            h, w = m.opacity.shape[:2]
            offset[i], size[i] = off, (w, h)
            chunks.append(np.ascontiguousarray(m.opacity, np.float32).reshape(-1))
            off += w * h
    uv = np.zeros((1, 6))
    if (kind == PASS_MASK).any() and scene.uvs is not None:
        uv = np.ascontiguousarray(scene.uvs[scene.triangles[tri_index]].reshape(-1, 6), np.float64)
    elif (kind == PASS_MASK).any():   # no texture coordinates: the factor's alpha alone decides
        uv = np.zeros((len(tri_index), 6))
    data = np.concatenate(chunks) if chunks else np.zeros(1, np.float32)
    return kind, mat, uv, offset, size, alpha, cutoff, data, tint


def _wide(lo, hi, right, first, count):
    """The 8-wide records (kernels/bvh.py, WIDE_*), 64-byte aligned so each
    is four cache lines; boxes rounded outward to float32."""
    boxes, child, cnt = collapse_wide(lo, hi, right, first, count, WIDTH)
    nw = len(boxes)
    raw = np.zeros(nw * WIDE_RECORD + 16, np.float32)
    off = (-raw.ctypes.data % 64) // 4
    wide = raw[off:off + nw * WIDE_RECORD].reshape(nw, WIDE_RECORD)
    ints = wide.view(np.int32)
    b32 = _outward32(boxes.reshape(-1, 6)).reshape(nw, WIDTH, 6)
    for q in range(3):
        wide[:, WIDE_LO + WIDTH * q:WIDE_LO + WIDTH * (q + 1)] = b32[:, :, q]
        wide[:, WIDE_HI + WIDTH * q:WIDE_HI + WIDTH * (q + 1)] = b32[:, :, 3 + q]
    ints[:, WIDE_CHILD:WIDE_CHILD + WIDTH] = child
    ints[:, WIDE_COUNT:WIDE_COUNT + WIDTH] = cnt
    return wide


def build_scene_bvh(scene) -> BVH:
    """The scene's BVH with its pass tables (ray_passes)."""
    from dataclasses import replace
    bvh = build(scene.triangle_corners())
    return replace(bvh, passes=ray_passes(scene, bvh.tri_index))
