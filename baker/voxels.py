"""Sparse surface voxelization (METHOD.md section 2).

One voxel per (cell, facing, sheet): the exact pieces of the scene's
triangles clipped to a cell, grouped by the side they face (dominant axis
and sign of the normal) and split into sheets when pieces lie on planes
more than 0.1 h apart. Only surface cells exist: memory follows surface
area / h^2, never the bounding volume. The supercover of every triangle
(every cell its plane crosses with positive area) is 26-separating.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import BudgetError
from .kernels.voxelize import (cell_runs, clip_pieces, count_candidates, find_straddlers, merge_sheets,
                               separating_planes, side_signatures, split_pieces, textured_albedo)

SHEET_GAP = 0.1          # in cells: pieces on planes further apart are separate voxels
MIN_SPLIT_PART = 1e-6    # in cells^2: a piece is cut by another surface's plane when both parts are larger
MIN_SEPARATION = 0.01    # in cells: pieces this far on both sides of a surface's plane are told apart
MIN_PIECE_AREA = 1e-14   # in cells^2: below this a clipped piece is rounding noise (slivers above it
#                          are kept: a plane passing 1e-6 cell from a corner still separates the lines there)
BYTES_PER_CANDIDATE = 112  # pass-2 arrays per candidate cell (measured layout below)
BYTES_PER_VOXEL = 180      # the Voxels arrays and the sorting temporaries


@dataclass(frozen=True)
class Voxels:
    """The voxel set, sorted by (cell key, facing, sheet).

    origin (3,) float64 and cell_size h: cell (i, j, k) spans
    origin + h * [(i, j, k), (i+1, j+1, k+1)]; dims (3,) int64.
    cell (n, 3) int32; facing (n,) int8 (0..5 = +x,-x,+y,-y,+z,-z);
    key (n,) int64 = (i * dims[1] + j) * dims[2] + k;
    area (n,) float64 (scene units^2); normal (n, 3) unit, area-weighted;
    centroid (n, 3) area-weighted, a point on the surface; albedo (n, 3);
    emission (n, 3) emitted radiosity E = pi L_e; material (n,) int32 of
    the largest piece.
    """
    origin: np.ndarray
    cell_size: float
    dims: np.ndarray
    cell: np.ndarray
    facing: np.ndarray
    key: np.ndarray
    area: np.ndarray
    normal: np.ndarray
    centroid: np.ndarray
    albedo: np.ndarray
    emission: np.ndarray
    material: np.ndarray
    cut_plane: np.ndarray     # (n, 4) float32 plane of the surface that cut the voxel's pieces: normal, and offset
    #                           in grid units relative to the voxel's cell (n . (g - cell) = offset)
    cut_sign: np.ndarray      # (n,) int8 +1 / -1: the voxel lies in front of / behind it; 0: not cut
    two_sided: np.ndarray     # (n,) bool: its largest piece is double-sided (a sheet: its back is the voxel
    #                           of the other facing in the cell, at the same centroid)
    piece_key: np.ndarray     # (m,) int64 cell key of each piece, sorted by (side, cell key)
    piece_voxel: np.ndarray   # (m,) int64 voxel of each piece
    piece_plane: np.ndarray   # (m, 4) float32 plane that cut a piece in two (as cut_plane, relative to its cell)
    piece_sign: np.ndarray    # (m,) int8 +1 / -1: the part in front of / behind that plane; 0: not cut
    side_start: np.ndarray    # (ns + 1,) pieces of side s are side_start[s] .. side_start[s+1] - 1
    back_side: np.ndarray     # (nt,) int32 side index of a triangle's back (-1: one-sided)

    def __len__(self):
        return len(self.area)

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, f).nbytes for f in ("cell", "facing", "key", "area", "normal", "centroid",
                                                     "albedo", "emission", "material", "cut_plane", "cut_sign",
                                                     "two_sided", "piece_key",
                                                     "piece_voxel", "piece_plane", "piece_sign", "side_start",
                                                     "back_side"))

    def lookup(self, cell_key, facing):
        """Voxel index range [lo, hi) of (cell key, facing); empty if none."""
        lo = np.searchsorted(self.key, cell_key, "left")
        hi = np.searchsorted(self.key, cell_key, "right")
        sel = np.arange(lo, hi)[self.facing[lo:hi] == facing]
        return sel


def _relative_plane(plane, cell):
    """(normal, offset) in grid units -> float32 (normal, offset - normal . cell):
    small numbers, exact enough in float32 on any grid."""
    out = plane.copy()
    out[:, 3] -= (plane[:, :3] * cell).sum(axis=1)
    return out.astype(np.float32)


def grid_for(scene, resolution: int = 64, cell_size: float = 0.0):
    """(origin, h, dims): cells of size h (cell_size, or the longest axis /
    resolution) with one cell of margin on every side."""
    lo, hi = scene.bounds()
    extent = float((hi - lo).max())
    if extent <= 0:
        extent = 1.0
    h = float(cell_size) if cell_size and cell_size > 0 else extent / int(resolution)
    origin = lo - h
    dims = (np.floor((hi - lo) / h).astype(np.int64) + 3)
    if np.any(dims >= 2 ** 21):
        raise BudgetError(f"grid of {dims.tolist()} cells exceeds 2^21 per axis: use a larger cell size",
                          scene.path)
    return origin, h, dims


def estimate(scene, resolution=64, cell_size=0.0):
    """Pass 1 only: (candidate cells, estimated bytes) without allocating pieces."""
    origin, h, dims = grid_for(scene, resolution, cell_size)
    sides_tri, sides_sign = _sides(scene)
    counts = count_candidates(scene.triangle_corners(), sides_tri, sides_sign, origin, 1.0 / h)
    total = int(counts.sum())
    return total, total * (BYTES_PER_CANDIDATE + BYTES_PER_VOXEL)


def _sides(scene):
    ds = scene.double_sided[scene.material_ids]
    nt = len(scene.triangles)
    front = np.arange(nt, dtype=np.int32)
    back = np.nonzero(ds)[0].astype(np.int32)
    return np.concatenate([front, back]), np.concatenate([np.ones(nt, np.int32), -np.ones(len(back), np.int32)])


def voxelize(scene, resolution: int = 64, cell_size: float = 0.0, memory_budget_mb: float = 8192.0,
             surfaces=None) -> Voxels:
    """Scene -> Voxels. Raises BudgetError (with the estimate) before
    allocating when the estimate exceeds memory_budget_mb."""
    from . import surfaces as surf_mod
    origin, h, dims = grid_for(scene, resolution, cell_size)
    corners = scene.triangle_corners()
    sides_tri, sides_sign = _sides(scene)
    inv_h = 1.0 / h
    counts = count_candidates(corners, sides_tri, sides_sign, origin, inv_h)
    total = int(counts.sum())
    need_mb = total * (BYTES_PER_CANDIDATE + BYTES_PER_VOXEL) / 2 ** 20
    if need_mb > memory_budget_mb:
        raise BudgetError(f"voxelization at {dims.max() - 3} cells ({h:.4g} per cell) needs about {need_mb:.0f} MiB "
                          f"({total} candidate cells), over the budget of {memory_budget_mb:.0f} MiB: lower the "
                          f"resolution or raise the budget", scene.path)
    offsets = np.zeros(len(counts), np.int64)
    np.cumsum(counts[:-1], out=offsets[1:])
    p_cell = np.empty((total, 3), np.int32)
    p_area = np.empty(total)
    p_cen = np.empty((total, 3))
    p_nrm = np.empty((total, 3))
    p_side = np.empty(total, np.int32)
    clip_pieces(corners, sides_tri, sides_sign, origin, inv_h, offsets, dims, p_cell, p_area, p_cen, p_nrm, p_side)
    keep = p_area > MIN_PIECE_AREA
    p_cell, p_area, p_cen, p_nrm, p_side = p_cell[keep], p_area[keep], p_cen[keep], p_nrm[keep], p_side[keep]

    def keys_and_facings():
        k = (p_cell[:, 0].astype(np.int64) * dims[1] + p_cell[:, 1]) * dims[2] + p_cell[:, 2]
        ax = np.argmax(np.abs(p_nrm), axis=1)
        return k, (2 * ax + (p_nrm[np.arange(len(ax)), ax] < 0)).astype(np.int8), ax
    key, facing, axis = keys_and_facings()
    # straddling pieces (a floor running under a wall): cut by the other surface's plane
    p_tri = sides_tri[p_side]
    by_cell = np.argsort(key, kind="stable")
    cut = find_straddlers(by_cell, cell_runs(by_cell, key), key, facing, p_tri, p_cell, p_area, p_cen, p_nrm,
                          corners, origin, inv_h, MIN_SPLIT_PART)
    n0 = len(p_area)
    split = np.nonzero(cut >= 0)[0]
    p_plane = np.zeros((n0 + len(split), 4))
    p_sign = np.zeros(n0 + len(split), np.int8)
    if len(split):
        extra = np.full(n0, -1, np.int64)
        extra[split] = n0 + np.arange(len(split))
        p_cell = np.concatenate([p_cell, p_cell[split]])
        p_nrm = np.concatenate([p_nrm, p_nrm[split]])
        p_side = np.concatenate([p_side, p_side[split]])
        p_area = np.concatenate([p_area, np.zeros(len(split))])
        p_cen = np.concatenate([p_cen, np.zeros((len(split), 3))])
        split_pieces(cut, p_tri, p_cell, p_area, p_cen, p_nrm, corners, origin, inv_h, extra, p_area, p_cen,
                     p_plane, p_sign)
        key, facing, axis = keys_and_facings()
    # cells crossed by a surface: where a piece was cut (a floor running under a wall) or where a piece's
    # plane separates others (a wall between two floors), every other piece not parallel to that plane
    # takes its side of it; voxels then know the surface stands there (kernels/propagate.py, _cut_between)
    cell_plane = np.zeros((len(p_area), 4))
    has = np.zeros(len(p_area), np.bool_)
    by_cell = np.argsort(key, kind="stable")
    runs = cell_runs(by_cell, key)
    separating_planes(by_cell, runs, sides_tri[p_side], p_area, p_cen, p_nrm, MIN_SEPARATION, cell_plane, has)
    if (p_sign != 0).any():
        cut_keys, first = np.unique(key[p_sign != 0], return_index=True)
        planes = p_plane[p_sign != 0][first]
        where = np.minimum(np.searchsorted(cut_keys, key), len(cut_keys) - 1)
        in_cut = cut_keys[where] == key
        cell_plane[in_cut] = planes[where[in_cut]]
        has |= in_cut
    idx = np.nonzero(has & (p_sign == 0))[0]
    pl = cell_plane[idx]
    nrm = p_nrm[idx] / np.linalg.norm(p_nrm[idx], axis=1, keepdims=True)
    crossing = np.abs(np.einsum("ij,ij->i", nrm, pl[:, :3])) < 0.9  # the crossing surface itself is not cut
    idx, pl = idx[crossing], pl[crossing]
    side = np.einsum("ij,ij->i", p_cen[idx] / p_area[idx, None], pl[:, :3]) - pl[:, 3]
    p_plane[idx] = pl
    p_sign[idx] = np.where(side >= 0, 1, -1)
    along = p_cen[np.arange(len(axis)), axis] / p_area
    sig = side_signatures(by_cell, runs, key, facing, p_area, p_cen, p_nrm, SHEET_GAP)
    # the two parts of a cut piece never merge: fold the part into the signature
    group = np.unique(np.stack([sig, p_sign.astype(np.int64)], axis=1), axis=0, return_inverse=True)[1].ravel()
    order = np.lexsort((along, group, facing, key))
    vox_of = merge_sheets(order, key, facing, group, along, p_area, p_cen, p_nrm, SHEET_GAP)
    n = int(vox_of[-1]) + 1 if len(vox_of) else 0
    # per-voxel sums in sorted piece order (deterministic)
    tri = sides_tri[p_side]
    area = np.bincount(vox_of, weights=p_area[order], minlength=n)
    cen = np.stack([np.bincount(vox_of, weights=p_cen[order, c], minlength=n) for c in range(3)], axis=1)
    nrm = np.stack([np.bincount(vox_of, weights=p_nrm[order, c] * p_area[order], minlength=n) for c in range(3)],
                   axis=1)
    mats = scene.material_ids[tri]
    albedo_mat = scene.albedo.astype(np.float64)
    textured = np.array([m.texture is not None for m in scene.materials]) & (scene.uvs is not None)
    p_alb = albedo_mat[mats]
    if textured[mats].any():
        surf = surfaces or surf_mod.pack(scene)
        sel = np.nonzero(textured[mats])[0]
        p_alb[sel] = textured_albedo(surf.arrays, corners, tri[sel].astype(np.int32), p_cell[sel].astype(np.int64),
                                     origin, h, 4)
    em_mat = np.pi * scene.emission.astype(np.float64)
    # a one-sided emitter's back is black: only the front side (sign +1) emits
    side_emits = (sides_sign[p_side] > 0) | scene.double_sided[mats]
    p_em = em_mat[mats] * side_emits[:, None]
    w = p_area[order]
    alb = np.stack([np.bincount(vox_of, weights=p_alb[order, c] * w, minlength=n) for c in range(3)], axis=1)
    em = np.stack([np.bincount(vox_of, weights=p_em[order, c] * w, minlength=n) for c in range(3)], axis=1)
    # material of the largest piece
    big = np.lexsort((-w, vox_of))
    first = np.ones(len(big), bool)
    first[1:] = vox_of[big[1:]] != vox_of[big[:-1]]
    material = mats[order][big[first]].astype(np.int32)
    starts = np.ones(len(vox_of), bool)
    starts[1:] = vox_of[1:] != vox_of[:-1]
    cell = p_cell[order][starts]
    cut_plane = _relative_plane(p_plane[order][starts], p_cell[order][starts])
    cut_sign = p_sign[order][starts]
    nl = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.where(nl > 0, nrm / np.maximum(nl, 1e-300), 0.0)
    # (side, cell) -> voxel: where a photon or a camera ray that hit a
    # triangle's side in a cell lands, exactly, whatever the sheets and splits
    side_sorted = p_side[order]
    key_sorted = key[order]
    by_side = np.lexsort((key_sorted, side_sorted))
    ns = len(sides_tri)
    side_start = np.searchsorted(side_sorted[by_side], np.arange(ns + 1)).astype(np.int64)
    back_side = np.full(len(scene.triangles), -1, np.int32)
    nt = len(scene.triangles)
    back_side[sides_tri[nt:]] = np.arange(nt, ns, dtype=np.int32)
    return Voxels(origin=origin, cell_size=h, dims=dims, cell=cell.astype(np.int32),
                  facing=facing[order][starts], key=key[order][starts], area=area * h * h,
                  normal=nrm, centroid=origin + cen / area[:, None] * h, albedo=alb / area[:, None],
                  emission=em / area[:, None], material=material, cut_plane=cut_plane, cut_sign=cut_sign,
                  two_sided=scene.double_sided[material].astype(bool),
                  piece_key=key_sorted[by_side],
                  piece_voxel=vox_of[by_side].astype(np.int64),
                  piece_plane=_relative_plane(p_plane[order][by_side], p_cell[order][by_side]),
                  piece_sign=p_sign[order][by_side], side_start=side_start, back_side=back_side)
