"""Sparse surface voxelization (docs/design.md section 2).

One voxel per (cell, facing, sheet): the exact pieces of the scene's
triangles clipped to a cell, grouped by the side they face (dominant axis
and sign of the normal) and split into sheets when pieces lie on planes
more than SHEET_GAP apart. Only surface cells exist: memory follows surface
area / h^2, never the bounding volume. The supercover of every triangle
(every cell its plane crosses with positive area) is 26-separating.

`voxelize` runs these steps, each a function below:

1. grid: cell size and extent (`grid_for`);
2. budget: refuse before allocating when the voxels cannot fit
   (`check_budget`, an O(triangles) lower bound first);
3. clip: every triangle side clipped to every cell its plane crosses
   (`clip_sides`);
3b. passing: pieces light mostly goes through (thin glass, mostly
   cut-out masked pieces) are left out (`drop_passing`);
4. patches: the pieces of a cell that belong to one smooth surface
   (`find_patches`, patches.py): a patch never cuts, separates or splits
   itself in the next steps;
4b. straddlers: a piece that another surface's plane cuts in two inside
   the cell (a floor running under a wall) becomes two parts
   (`cut_straddlers`);
5. crossed cells: every piece of a cell that a surface crosses learns its
   side of that surface (`mark_crossed_cells`);
6. sheets: pieces merge into voxels per (cell, facing, sheet, side),
   and the pieces of one patch of one facing and side always merge
   (`group_pieces`);
6b. clutter: a cell with more than CLUTTER_VOXELS voxels merges its small
   ones per facing (`merge_clutter`): cost bounded per cell;
6c. buried parts: each piece counts with the share of its points that do
   not lie inside another object (`buried_weights`, buried.py): the parts
   pushed into other parts take no share of the light;
7. sums: area, centroid, normal, albedo, emission per voxel (`voxel_sums`);
8. lookup: (triangle side, cell) -> voxel, for photons and camera rays
   (`piece_lookup`).
"""
from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from ..errors import BudgetError
from ..startup import checkpoint
from .albedo import mask_arrays, textured_albedo
from .cells import (cell_runs, find_straddlers, join_voxels, merge_sheets, separating_planes, side_signatures,
                    split_pieces)
from .clip import clip_pieces, count_candidates
from .buried import piece_weights, voxel_relative
from ..scene.topology import triangle_adjacency
from .patches import smooth_patches
from .tolerances import (CLUTTER_AREA, CLUTTER_PIECES, CLUTTER_VOXELS, FLAT_COS, MIN_PIECE_AREA, MIN_SEPARATION, MIN_SPLIT_PART, PARALLEL_COS, SHEET_GAP,
                         SMOOTH_COS)

BYTES_PER_CANDIDATE = 112  # pass-2 arrays per candidate cell (measured layout below)
BYTES_PER_VOXEL = 180      # the Voxels arrays and the sorting temporaries
MAX_CELLS_PER_AXIS = 2 ** 21


# The kernels' views of a Voxels (its .lookup() and .arrays()); the fields as Voxels documents them, h its
# cell_size.
PieceLookup = namedtuple("PieceLookup", ["key", "voxel", "plane", "sign", "side_start", "back_side", "origin", "h",
                                         "dims"])
VoxelArrays = namedtuple("VoxelArrays", ["key", "cell", "centroid", "normal", "area", "cut_plane", "cut_sign"])


@dataclass(frozen=True)
class Voxels:
    """The voxel set, sorted by (cell key, facing, sheet).

    origin (3,) float64 and cell_size h: cell (i, j, k) spans
    origin + h * [(i, j, k), (i+1, j+1, k+1)]; dims (3,) int64.
    cell (n, 3) int32; facing (n,) int8 (0..5 = +x,-x,+y,-y,+z,-z);
    key (n,) int64 = (i * dims[1] + j) * dims[2] + k;
    area (n,) float64 (scene units^2: the pieces' area, each weighted by
    its share not buried in another object, buried.py, and a masked piece
    by its coverage);
    normal (n, 3) unit, area-weighted;
    centroid (n, 3) area-weighted, a point on the surface (scene units);
    albedo (n, 3); emission (n, 3) emitted radiosity E = pi L_e (W/m^2);
    material (n,) int32 of the largest piece.
    """
    origin: np.ndarray
    cell_size: float
    dims: np.ndarray
    cell: np.ndarray
    facing: np.ndarray
    key: np.ndarray
    area: np.ndarray
    surface_area: np.ndarray  # (n,) float64 the pieces' plain area, the parts buried in other objects included
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
    planar: np.ndarray        # (n,) bool: its pieces' normals agree within FLAT_COS (one plane, or nearly)
    piece_key: np.ndarray     # (m,) int64 cell key of each piece, sorted by (side, cell key)
    piece_voxel: np.ndarray   # (m,) int64 voxel of each piece
    piece_plane: np.ndarray   # (m, 4) float32 plane that cut a piece in two (as cut_plane, relative to its cell)
    piece_sign: np.ndarray    # (m,) int8 +1 / -1: the part in front of / behind that plane; 0: not cut
    side_start: np.ndarray    # (ns + 1,) pieces of side s are side_start[s] .. side_start[s+1] - 1
    back_side: np.ndarray     # (nt,) int32 side index of a triangle's back (-1: one-sided)

    def __len__(self):
        return len(self.area)

    def lookup(self) -> "PieceLookup":
        """The kernels' view of the pieces: which voxel holds a surface
        point (lookup.voxel_of_hit)."""
        return PieceLookup(self.piece_key, self.piece_voxel, self.piece_plane, self.piece_sign, self.side_start,
                           self.back_side, self.origin, float(self.cell_size), self.dims)

    def arrays(self) -> "VoxelArrays":
        """The kernels' view of the voxels themselves (the preview's texel
        values, lightmap/voxel_irradiance.py)."""
        return VoxelArrays(self.key, self.cell, self.centroid, self.normal, self.area, self.cut_plane, self.cut_sign)

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, f).nbytes for f in ("cell", "facing", "key", "area", "normal", "centroid",
                                                     "albedo", "emission", "material", "cut_plane", "cut_sign",
                                                     "two_sided", "planar", "piece_key", "piece_voxel", "piece_plane",
                                                     "piece_sign", "side_start", "back_side"))


@dataclass(frozen=True)
class Grid:
    """origin (3,) float64, cell size h (scene units), dims (3,) int64 cells."""
    origin: np.ndarray
    h: float
    dims: np.ndarray


@dataclass
class Pieces:
    """Triangle sides clipped to cells, in grid units: cell (m, 3) int32,
    area (m,) cells^2, centroid (m, 3) area-weighted sums, normal (m, 3)
    unit, side (m,) int32, (after step 4) patch (m,) int64 its smooth
    patch and surface (m,) int64 that patch with its other face, and (after step 4b/5) plane (m, 4) of a surface that cut or
    crosses the piece's cell with sign (m,) int8 its side and plane_patch
    (m,) int64 that surface's id (-1: none)."""
    cell: np.ndarray
    area: np.ndarray
    centroid: np.ndarray
    normal: np.ndarray
    side: np.ndarray
    patch: np.ndarray | None = None
    surface: np.ndarray | None = None
    plane: np.ndarray | None = None
    sign: np.ndarray | None = None
    plane_patch: np.ndarray | None = None

    def keys_and_facings(self, dims):
        """(cell key (m,) int64, facing (m,) int8, dominant axis (m,))."""
        k = (self.cell[:, 0].astype(np.int64) * dims[1] + self.cell[:, 1]) * dims[2] + self.cell[:, 2]
        ax = np.argmax(np.abs(self.normal), axis=1)
        return k, (2 * ax + (self.normal[np.arange(len(ax)), ax] < 0)).astype(np.int8), ax


def grid_for(scene, resolution: int = 64, cell_size: float = 0.0) -> Grid:
    """Cells of size h (cell_size, or the longest axis / resolution) with one
    cell of margin on every side."""
    lo, hi = scene.bounds()
    extent = float((hi - lo).max())
    if extent <= 0:
        extent = 1.0
    h = float(cell_size) if cell_size and cell_size > 0 else extent / int(resolution)
    origin = lo - h
    dims = np.floor((hi - lo) / h).astype(np.int64) + 3
    if np.any(dims >= MAX_CELLS_PER_AXIS):
        raise BudgetError(f"grid of {dims.tolist()} cells exceeds 2^21 per axis: use a larger cell size",
                          scene.path)
    return Grid(origin, h, dims)


def resolution_for(scene, config) -> int:
    """Cells along the scene's longest axis for a SolverConfig: its
    resolution, else one from its surface cells (unused when its cell_size
    is set)."""
    if config.resolution > 0 or config.cell_size > 0:
        return int(config.resolution)
    return surface_resolution(scene, config.surface_cells)


def surface_resolution(scene, surface_cells: int) -> int:
    """Cells along the longest axis such that the surfaces cover about
    surface_cells cells: their area projected on each side's dominant axis
    plane (the columns a side crosses, close to its voxel count: within
    10-60% on the test scenes, more where cells hold several sheets) over
    h^2. The cell size then follows the surfaces, not the bounding box."""
    lo, hi = scene.bounds()
    extent = float((hi - lo).max())
    corners = scene.triangle_corners()
    if extent <= 0 or not len(corners):
        return 1
    from ..scene.surfaces import VOXEL_PASS
    sides_tri, _ = _sides(scene)
    sides_tri = sides_tri[scene.transmission[scene.material_ids[sides_tri]] < VOXEL_PASS]  # glass makes no voxels
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    projected = float(0.5 * np.abs(cross).max(axis=1)[sides_tri].sum())  # in scene units^2
    if projected <= 0:
        return 1
    res = int(round(extent * np.sqrt(surface_cells / projected)))
    return int(min(max(res, 1), MAX_CELLS_PER_AXIS - 4))


def _sides(scene):
    """Triangle sides: (triangle (ns,) int32, sign (ns,) int32 +1 front / -1
    back); fronts first in triangle order, then the backs of double-sided
    triangles."""
    ds = scene.double_sided[scene.material_ids]
    nt = len(scene.triangles)
    front = np.arange(nt, dtype=np.int32)
    back = np.nonzero(ds)[0].astype(np.int32)
    return np.concatenate([front, back]), np.concatenate([np.ones(nt, np.int32), -np.ones(len(back), np.int32)])


def candidate_bound(corners, sides_tri, grid: Grid) -> int:
    """A lower bound of the candidate cells in O(triangles): each side's
    area projected on its dominant axis plane, in cells^2 (every column of
    cells it crosses holds at least one candidate, and the columns cover
    the projection)."""
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    cross = np.cross(e1, e2)
    projected = 0.5 * np.abs(cross).max(axis=1) / grid.h ** 2
    return int(projected[sides_tri].sum())


def check_budget(scene, grid: Grid, corners, sides_tri, sides_sign, memory_budget_mb: float):
    """Candidate cells per side (ns,) int64 (pass 1), after refusing with a
    BudgetError when the voxelization cannot fit memory_budget_mb: first
    from the O(triangles) lower bound, so that an absurd resolution is
    refused at once, then from the exact count."""
    per = BYTES_PER_CANDIDATE + BYTES_PER_VOXEL

    def refuse(cells, what):
        need = cells * per / 2 ** 20
        raise BudgetError(f"voxelization at {grid.dims.max() - 3} cells ({grid.h:.4g} per cell) needs about "
                          f"{need:.0f} MiB ({what} {cells} candidate cells), over the budget of "
                          f"{memory_budget_mb:.0f} MiB: lower the resolution or raise the budget", scene.path)
    low = candidate_bound(corners, sides_tri, grid)
    if low * per / 2 ** 20 > memory_budget_mb:
        refuse(low, "at least")
    counts = count_candidates(corners, sides_tri, sides_sign, grid.origin, 1.0 / grid.h)
    total = int(counts.sum())
    if total * per / 2 ** 20 > memory_budget_mb:
        refuse(total, "")
    return counts


def estimate(scene, resolution=64, cell_size=0.0):
    """Pass 1 only: (candidate cells, estimated bytes) without allocating pieces."""
    grid = grid_for(scene, resolution, cell_size)
    sides_tri, sides_sign = _sides(scene)
    counts = count_candidates(scene.triangle_corners(), sides_tri, sides_sign, grid.origin, 1.0 / grid.h)
    total = int(counts.sum())
    return total, total * (BYTES_PER_CANDIDATE + BYTES_PER_VOXEL)


def clip_sides(corners, sides_tri, sides_sign, grid: Grid, counts) -> Pieces:
    """Step 3: every side clipped to its candidate cells; pieces under
    MIN_PIECE_AREA (rounding noise) dropped."""
    total = int(counts.sum())
    offsets = np.zeros(len(counts), np.int64)
    np.cumsum(counts[:-1], out=offsets[1:])
    cell = np.empty((total, 3), np.int32)
    area = np.empty(total)
    cen = np.empty((total, 3))
    nrm = np.empty((total, 3))
    side = np.empty(total, np.int32)
    clip_pieces(corners, sides_tri, sides_sign, grid.origin, 1.0 / grid.h, offsets, grid.dims, cell, area, cen, nrm,
                side)
    keep = area > MIN_PIECE_AREA
    return Pieces(cell[keep], area[keep], cen[keep], nrm[keep], side[keep])


def drop_passing(pieces: Pieces, piece_tri, scene, grid: Grid, surfaces=None) -> Pieces:
    """Step 3b: the pieces light mostly goes through are left out: thin
    glass with t >= VOXEL_PASS and masked pieces less than half covered
    (their coverage from the alpha test at the albedo's sample points).
    A voxel's line is either stopped or clear; these surfaces let through
    more than they stop. A masked piece that stays keeps its coverage as
    its area (it reflects from its covered part only; photons land there
    only)."""
    from ..scene.surfaces import VOXEL_PASS, pack
    mats = scene.material_ids[piece_tri]
    drop = scene.transmission[mats] >= VOXEL_PASS
    masked = np.array([m.masked for m in scene.materials])[mats]
    if masked.any():
        sel = np.nonzero(masked & ~drop)[0]
        surf = surfaces or pack(scene)
        _, cover, _ = textured_albedo(surf.arrays, mask_arrays(scene), scene.triangle_corners(),
                                      piece_tri[sel].astype(np.int32), pieces.cell[sel].astype(np.int64),
                                      grid.origin, grid.h, 4)
        drop[sel] = cover < 1.0 - VOXEL_PASS
        scale = np.ones(len(pieces.area))
        scale[sel] = cover
        pieces = Pieces(pieces.cell, pieces.area * scale, pieces.centroid * scale[:, None], pieces.normal,
                        pieces.side)
    if not drop.any():
        return pieces
    keep = ~drop
    return Pieces(pieces.cell[keep], pieces.area[keep], pieces.centroid[keep], pieces.normal[keep], pieces.side[keep])


def find_patches(pieces: Pieces, piece_tri, scene, grid: Grid) -> Pieces:
    """Step 4: each piece's smooth patch (patches.py)."""
    key, _, _ = pieces.keys_and_facings(grid.dims)
    by_cell = np.argsort(key, kind="stable")
    adj_start, adj = triangle_adjacency(scene.vertices, scene.triangles)
    patch, surface = smooth_patches(by_cell, cell_runs(by_cell, key), piece_tri.astype(np.int64), pieces.normal,
                                    adj_start, adj, SMOOTH_COS)
    return Pieces(pieces.cell, pieces.area, pieces.centroid, pieces.normal, pieces.side, patch, surface)


def cut_straddlers(pieces: Pieces, piece_tri, corners, grid: Grid) -> Pieces:
    """Step 4b: a piece that another surface's plane cuts into two parts of
    at least MIN_SPLIT_PART (a floor running under a wall) is replaced by
    its front part (sign +1) and its back part (sign -1, appended), both
    remembering the plane and its patch."""
    key, facing, _ = pieces.keys_and_facings(grid.dims)
    by_cell = np.argsort(key, kind="stable")
    inv_h = 1.0 / grid.h
    cut = find_straddlers(by_cell, cell_runs(by_cell, key), key, facing, piece_tri, pieces.cell, pieces.area,
                          pieces.centroid, pieces.normal, corners, grid.origin, inv_h, MIN_SPLIT_PART, pieces.surface,
                          CLUTTER_PIECES, CLUTTER_AREA)
    n0 = len(pieces.area)
    split = np.nonzero(cut >= 0)[0]
    plane = np.zeros((n0 + len(split), 4))
    sign = np.zeros(n0 + len(split), np.int8)
    plane_patch = np.full(n0 + len(split), -1, np.int64)
    plane_patch[split] = pieces.surface[cut[split]]
    plane_patch[n0:] = pieces.surface[cut[split]]
    patch = np.concatenate([pieces.patch, pieces.patch[split]])
    surface = np.concatenate([pieces.surface, pieces.surface[split]])
    if not len(split):
        return Pieces(pieces.cell, pieces.area, pieces.centroid, pieces.normal, pieces.side, patch, surface, plane,
                      sign, plane_patch)
    extra = np.full(n0, -1, np.int64)
    extra[split] = n0 + np.arange(len(split))
    cell = np.concatenate([pieces.cell, pieces.cell[split]])
    nrm = np.concatenate([pieces.normal, pieces.normal[split]])
    side = np.concatenate([pieces.side, pieces.side[split]])
    area = np.concatenate([pieces.area, np.zeros(len(split))])
    cen = np.concatenate([pieces.centroid, np.zeros((len(split), 3))])
    split_pieces(cut, piece_tri, cell, area, cen, nrm, corners, grid.origin, inv_h, extra, area, cen, plane, sign)
    return Pieces(cell, area, cen, nrm, side, patch, surface, plane, sign, plane_patch)


def mark_crossed_cells(pieces: Pieces, key, piece_tri):
    """Step 5: cells crossed by a surface, where a piece was cut (a floor
    running under a wall) or where a piece's plane separates others (a wall
    between two floors): every other piece not parallel to that plane takes
    its side of it (in place), so that its voxel knows the surface stands
    there (the propagation's cut test, docs/design.md section 4); the
    pieces of that surface's own patch do not."""
    n = len(pieces.area)
    cell_plane = np.zeros((n, 4))
    has = np.zeros(n, np.bool_)
    by_cell = np.argsort(key, kind="stable")
    runs = cell_runs(by_cell, key)
    separating_planes(by_cell, runs, piece_tri, pieces.area, pieces.centroid, pieces.normal, MIN_SEPARATION,
                      pieces.surface, cell_plane, has)
    cut = pieces.sign != 0
    if cut.any():
        cut_keys, first = np.unique(key[cut], return_index=True)
        planes = pieces.plane[cut][first]
        owner = pieces.plane_patch[cut][first]
        where = np.minimum(np.searchsorted(cut_keys, key), len(cut_keys) - 1)
        in_cut = (cut_keys[where] == key) & (pieces.surface != owner[where])
        cell_plane[in_cut] = planes[where[in_cut]]
        has |= in_cut
    idx = np.nonzero(has & ~cut)[0]
    pl = cell_plane[idx]
    nrm = pieces.normal[idx] / np.linalg.norm(pieces.normal[idx], axis=1, keepdims=True)
    crossing = np.abs(np.einsum("ij,ij->i", nrm, pl[:, :3])) < PARALLEL_COS  # the crossing surface itself is not cut
    idx, pl = idx[crossing], pl[crossing]
    side = np.einsum("ij,ij->i", pieces.centroid[idx] / pieces.area[idx, None], pl[:, :3]) - pl[:, 3]
    pieces.plane[idx] = pl
    pieces.sign[idx] = np.where(side >= 0, 1, -1)
    return by_cell, runs


def group_pieces(pieces: Pieces, key, facing, axis, by_cell, runs, two_sided):
    """Step 6: (order (m,) of the pieces, voxel of each piece in that order
    (m,) int64). Pieces of a (cell, facing) merge unless another surface of
    the cell separates them (side signatures), they are the two parts of a
    cut piece, or their planes lie over SHEET_GAP apart (sheets); but the
    pieces of one smooth patch and facing merge despite the gap (a curved
    surface's pieces lie on planes apart by its curvature), unless another
    surface separates or cuts them. A face of a two-sided surface (two_sided
    (m,) bool per piece) merges only with pieces of its own surface
    (patches.py): lying on another surface's plane, it is that surface's
    other side across its own sheet (a scan's closed bottom resting on a
    floor: the floor's top and the bottom's inner face coincide)."""
    along = pieces.centroid[np.arange(len(axis)), axis] / pieces.area
    sig = side_signatures(by_cell, runs, key, facing, pieces.area, pieces.centroid, pieces.normal, SHEET_GAP,
                          pieces.surface, CLUTTER_PIECES, CLUTTER_AREA)
    # the two parts of a cut piece never merge: fold the part into the signature; and a two-sided surface's
    # face keeps to its own surface
    group = _labels(sig, pieces.sign.astype(np.int64), np.where(two_sided, pieces.surface, -1))
    order = np.lexsort((along, group, facing, key))
    vox_of = merge_sheets(order, key, facing, group, along, pieces.area, pieces.centroid, pieces.normal, SHEET_GAP)
    # join the voxels holding pieces of one (patch, facing, signature and part, cutting surface), then renumber
    # in order of first piece (the voxels stay in cell order) and make each voxel's pieces contiguous
    keys = [k[order] for k in (pieces.patch, facing.astype(np.int64), group, pieces.plane_patch)]
    same = np.lexsort(keys[::-1])
    link = np.zeros(len(order), bool)
    link[1:] = np.logical_and.reduce([k[same][1:] == k[same][:-1] for k in keys])
    link[1:] &= vox_of[same][1:] != vox_of[same][:-1]  # only pairs in different voxels join anything
    if link.any():
        root = join_voxels(vox_of, same, link)[vox_of]
        _, first, inv = np.unique(root, return_index=True, return_inverse=True)
        rank = np.empty(len(first), np.int64)
        rank[np.argsort(first, kind="stable")] = np.arange(len(first))
        new_of = rank[inv.ravel()]
        resort = np.argsort(new_of, kind="stable")
        order, vox_of = order[resort], new_of[resort]
    return merge_clutter(order, vox_of, key, facing, pieces.area)


def merge_clutter(order, vox_of, key, facing, area, cap=CLUTTER_VOXELS, small=CLUTTER_AREA):
    """Step 6b: bounds the voxels of a cell. A cell holding more than cap
    voxels (a chandelier's thousands of tiny parts, a plant's leaves: every
    part a sheet or a side of its own) keeps its voxels of at least small
    cells^2 (a wall, a floor) and merges the others into one voxel per
    facing; if that still leaves more than cap, every voxel of one facing
    merges. Detail far below a cell cannot be resolved by the propagation,
    and its cost grows with the voxels a line meets in a cell; the small
    parts' light then spreads over their cell's side (the lightmap keeps
    their own texels). The cap is high because a merged voxel gathers as
    if none of its parts shadowed another (a plant's inner leaves lit
    like its outer ones): merging at 12 voxels made the living room's
    plants, and the room with them, 20% too bright. Returns (order,
    vox_of) as group_pieces does."""
    n = int(vox_of[-1]) + 1 if len(vox_of) else 0
    starts = np.ones(len(vox_of), bool)
    starts[1:] = vox_of[1:] != vox_of[:-1]
    vkey, vface = key[order][starts], facing[order][starts].astype(np.int64)
    varea = np.bincount(vox_of, weights=area[order], minlength=n)
    _, cell_of, per_cell = np.unique(vkey, return_inverse=True, return_counts=True)
    crowded = per_cell[cell_of] > cap
    if not crowded.any():
        return order, vox_of
    merge = crowded & (varea < small)
    lab = np.where(merge, -1 - vface, np.arange(n))
    kept = np.zeros(len(per_cell), np.int64)
    np.add.at(kept, cell_of, lab >= 0)
    merged_faces = np.zeros((len(per_cell), 6), bool)
    merged_faces[cell_of[merge], vface[merge]] = True
    over = kept + merged_faces.sum(axis=1) > cap  # the large voxels alone are too many: merge by facing alone
    lab = np.where(over[cell_of], -1 - vface, lab)
    label = _labels(vkey, lab)  # cell order kept: the key is the first column
    new_of = label[vox_of]
    resort = np.argsort(new_of, kind="stable")
    return order[resort], new_of[resort]


def _labels(*columns):
    """An int64 label per row of the given int64 columns, equal exactly when
    the rows are equal."""
    order = np.lexsort(columns[::-1])
    change = np.zeros(len(order), bool)
    for c in columns:
        cs = c[order]
        change[1:] |= cs[1:] != cs[:-1]
    change[:1] = True
    label = np.empty(len(order), np.int64)
    label[order] = np.cumsum(change) - 1
    return label


def voxel_sums(scene, pieces: Pieces, order, vox_of, sides_tri, sides_sign, corners, grid: Grid, surfaces,
               weight=None):
    """Step 7: per-voxel area, centroid, normal, albedo (texture-aware),
    emission, material of the largest piece, cell and cut plane, summed in
    sorted piece order (deterministic). Returns a dict of Voxels fields."""
    n = int(vox_of[-1]) + 1 if len(vox_of) else 0
    tri = sides_tri[pieces.side]
    w = pieces.area[order]

    def per_voxel(values):  # (m, c) piece values in piece order -> (n, c) sums
        return np.stack([np.bincount(vox_of, weights=values[order, c], minlength=n) for c in range(values.shape[1])],
                        axis=1)
    plain = np.bincount(vox_of, weights=w, minlength=n)
    area = plain if weight is None else np.bincount(vox_of, weights=w * weight[order], minlength=n)
    cen = per_voxel(pieces.centroid)
    nrm = per_voxel(pieces.normal * pieces.area[:, None])
    mats = scene.material_ids[tri]
    has_uv = scene.uvs is not None
    textured = (np.array([m.texture is not None or (m.emission_texture is not None and m.emission.max() > 0)
                          for m in scene.materials]) & has_uv) | np.array([m.masked for m in scene.materials])
    # thin glass kept in the voxels (t < VOXEL_PASS) reflects what it does not transmit
    p_alb = scene.albedo.astype(np.float64)[mats] * (1.0 - scene.transmission[mats])[:, None]
    p_emit = scene.emission.astype(np.float64)[mats]
    if textured[mats].any():
        from ..scene.surfaces import pack
        surf = surfaces or pack(scene)
        sel = np.nonzero(textured[mats])[0]
        alb, _, emit = textured_albedo(surf.arrays, mask_arrays(scene), corners, tri[sel].astype(np.int32),
                                       pieces.cell[sel].astype(np.int64), grid.origin, grid.h, 4)
        p_alb[sel] = alb * (1.0 - scene.transmission[mats[sel]])[:, None]
        p_emit[sel] = emit
    # a one-sided emitter's back is black: only the front side (sign +1) emits
    side_emits = (sides_sign[pieces.side] > 0) | scene.double_sided[mats]
    p_em = np.pi * p_emit * side_emits[:, None]
    alb = per_voxel(p_alb * pieces.area[:, None])
    em = per_voxel(p_em * pieces.area[:, None])
    big = np.lexsort((-w, vox_of))  # the largest piece of each voxel first
    first = np.ones(len(big), bool)
    first[1:] = vox_of[big[1:]] != vox_of[big[:-1]]
    material = mats[order][big[first]].astype(np.int32)
    starts = np.ones(len(vox_of), bool)
    starts[1:] = vox_of[1:] != vox_of[:-1]
    cell = pieces.cell[order][starts]
    nl = np.linalg.norm(nrm, axis=1, keepdims=True)
    h = grid.h
    return dict(cell=cell.astype(np.int32), area=area * h * h, surface_area=plain * h * h,
                normal=np.where(nl > 0, nrm / np.maximum(nl, 1e-300), 0.0),
                centroid=grid.origin + cen / plain[:, None] * h, albedo=alb / plain[:, None],
                emission=em / plain[:, None], material=material,
                cut_plane=_relative_plane(pieces.plane[order][starts], cell), cut_sign=_common_sign(pieces.sign[order],
                                                                                                    starts),
                two_sided=scene.double_sided[material].astype(bool),
                planar=nl[:, 0] >= FLAT_COS * plain)


def _common_sign(sign, starts):
    """Per voxel, the cut side its pieces (sorted by voxel, starts (m,)
    marking each voxel's first) share, 0 where they differ (a merged
    clutter voxel: merge_clutter)."""
    first = np.flatnonzero(starts)
    lo, hi = np.minimum.reduceat(sign, first), np.maximum.reduceat(sign, first)
    return np.where(lo == hi, lo, 0).astype(sign.dtype)


def buried_weights(scene, pieces: Pieces, order, vox_of, grid: Grid, corners, sides_tri, bvh=None, surfaces=None,
                   executor=None):
    """Step 6c: each piece's share not buried in another object (buried.py),
    which its area counts with in its voxel's area: a piece pushed inside
    another part takes no share of the light its voxel receives."""
    if not len(order):
        return np.ones(len(pieces.area))
    if bvh is None:
        from ..scene import build_scene_bvh
        bvh = build_scene_bvh(scene)
    if surfaces is None:
        from ..scene import pack
        surfaces = pack(scene)
    w = piece_weights(bvh, surfaces, corners, sides_tri[pieces.side], pieces.cell, pieces.plane, pieces.sign,
                      grid.origin + pieces.centroid / pieces.area[:, None] * grid.h, pieces.normal, grid.origin, grid.h,
                      executor)
    vox_piece = np.empty(len(order), np.int64)
    vox_piece[order] = vox_of
    return voxel_relative(w, pieces.area, vox_piece, int(vox_of[-1]) + 1)


def piece_lookup(pieces: Pieces, key, order, vox_of, sides_tri, n_triangles):
    """Step 8: (side, cell) -> voxel, where a photon or a camera ray that hit
    a triangle's side in a cell lands, exactly, whatever the sheets and
    splits. Returns a dict of Voxels fields."""
    side_sorted = pieces.side[order]
    key_sorted = key[order]
    by_side = np.lexsort((key_sorted, side_sorted))
    ns = len(sides_tri)
    back_side = np.full(n_triangles, -1, np.int32)
    back_side[sides_tri[n_triangles:]] = np.arange(n_triangles, ns, dtype=np.int32)
    return dict(piece_key=key_sorted[by_side], piece_voxel=vox_of[by_side].astype(np.int64),
                piece_plane=_relative_plane(pieces.plane[order][by_side], pieces.cell[order][by_side]),
                piece_sign=pieces.sign[order][by_side],
                side_start=np.searchsorted(side_sorted[by_side], np.arange(ns + 1)).astype(np.int64),
                back_side=back_side)


def _relative_plane(plane, cell):
    """(normal, offset) in grid units -> float32 (normal, offset - normal . cell):
    small numbers, exact enough in float32 on any grid."""
    out = plane.copy()
    out[:, 3] -= (plane[:, :3] * cell).sum(axis=1)
    return out.astype(np.float32)


def voxelize(scene, resolution: int = 64, cell_size: float = 0.0, memory_budget_mb: float = 8192.0,
             surfaces=None, bvh=None, executor=None) -> Voxels:
    """Scene -> Voxels (the steps of the module docstring). Raises
    BudgetError (with the estimate) before allocating when the estimate
    exceeds memory_budget_mb. bvh: the scene's (built here if not given),
    for the pieces' buried share, whose blocks of pieces are tasks on
    `executor` (bake/executor.py; None: here, the same bits)."""
    grid = grid_for(scene, resolution, cell_size)
    corners = scene.triangle_corners()
    sides_tri, sides_sign = _sides(scene)
    counts = check_budget(scene, grid, corners, sides_tri, sides_sign, memory_budget_mb)
    checkpoint()
    pieces = clip_sides(corners, sides_tri, sides_sign, grid, counts)
    pieces = drop_passing(pieces, sides_tri[pieces.side], scene, grid, surfaces)
    checkpoint()
    pieces = find_patches(pieces, sides_tri[pieces.side], scene, grid)
    pieces = cut_straddlers(pieces, sides_tri[pieces.side], corners, grid)
    key, facing, axis = pieces.keys_and_facings(grid.dims)
    by_cell, runs = mark_crossed_cells(pieces, key, sides_tri[pieces.side])
    checkpoint()
    two_sided = scene.double_sided[scene.material_ids[sides_tri[pieces.side]]]
    order, vox_of = group_pieces(pieces, key, facing, axis, by_cell, runs, two_sided)
    checkpoint()
    weight = buried_weights(scene, pieces, order, vox_of, grid, corners, sides_tri, bvh, surfaces, executor)
    sums = voxel_sums(scene, pieces, order, vox_of, sides_tri, sides_sign, corners, grid, surfaces, weight)
    lookup = piece_lookup(pieces, key, order, vox_of, sides_tri, len(scene.triangles))
    starts = np.ones(len(vox_of), bool)
    starts[1:] = vox_of[1:] != vox_of[:-1]
    return Voxels(origin=grid.origin, cell_size=grid.h, dims=grid.dims, facing=facing[order][starts],
                  key=key[order][starts], **sums, **lookup)
