"""Which parts of each piece are buried inside another object.

Real scenes are built of parts pushed into each other: a stair's tread
into its stringer, a baluster into the tread, a board into the floor.
The parts inside are surface the voxelizer clips like any other, but no
light reaches them. In a voxel that holds both, the photons' power (and
every later bounce) would spread over the whole area, and the visible
part show only its share. Each piece counts in its voxel's area with
the share of its sample points that are not buried: a point is buried
when the rays over its hemisphere meet the object around it from behind
(against the winding of its closed surface), close by where the object
is two-sided (the test the texels use, lightmap/texels.inside_geometry).
A crevice between two objects' outer faces is not buried: light that
reaches it is spread over it.

A voxel keeps at least BURIED_KEEP of its plain area (voxel_relative): no
voxel's irradiance grows more than 1 / BURIED_KEEP times; one whose pieces
are all buried keeps all of it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.sampling import frame, spiral_hemisphere
from ..kernels.traverse import back_hit, enclosed_in_plane
from .albedo import r2_point
from .clip import side_axis
from .tolerances import BURIED_BACK, BURIED_FLOOR, BURIED_KEEP, BURIED_NEAR, BURIED_RAYS, BURIED_REACH, BURIED_SAMPLES


@njit(cache=True, inline="always")
def _buried(bvh, stack, double, mat_of, px, py, pz, nx, ny, nz, local, near):
    """1.0 where the point p (normal n) lies inside a closed object: of the
    rays over n's hemisphere (directions `local` about +z), at least
    BURIED_BACK first meet a triangle from behind (against its winding)
    and at least BURIED_NEAR a one-sided one, or a two-sided one within
    `near` where the rays along the surface meet from behind too (the
    texels' inside test, lightmap/texels.inside_geometry); else 0.0."""
    (tx, ty, tz), (bx, by, bz) = frame(nx, ny, nz)
    e = 1e-3 * near   # off the piece's own plane
    ox, oy, oz = px + e * nx, py + e * ny, pz + e * nz
    backs = close1 = close2 = 0
    n = len(local)
    for k in range(n):
        lx, ly, lz = local[k, 0], local[k, 1], local[k, 2]
        what = back_hit(bvh, stack, double, mat_of, ox, oy, oz, lx * tx + ly * bx + lz * nx,
                        lx * ty + ly * by + lz * ny, lx * tz + ly * bz + lz * nz, np.inf, near)
        backs += what > 0
        close1 += what == 2
        close2 += what == 3
        left = n - 1 - k
        if backs + left < BURIED_BACK * n or close1 + close2 + left < BURIED_NEAR * n:
            return 0.0   # the rest cannot reach the shares: most points, in open air, stop at half their rays
    if backs < BURIED_BACK * n or close1 + close2 < BURIED_NEAR * n:
        return 0.0
    if close1 >= BURIED_NEAR * n or enclosed_in_plane(bvh, stack, ox, oy, oz, tx, ty, tz, bx, by, bz, np.inf):
        return 1.0
    return 0.0


@njit(cache=True, parallel=True, error_model="numpy")
def buried_kernel(bvh, double, mat_of, corners, piece_tri, piece_cell, piece_plane, piece_sign, centroids, normals,
                  origin, h, samples, local, near, out):
    """out[i]: piece i's weight, the mean over samples^2 of its points
    (the R2 points over the cell's face across the triangle's dominant
    axis, projected on its plane, kept inside the triangle, the cell and,
    for a piece that another surface's plane cut, on its side of that
    plane, as albedo.textured_albedo; its centroid if none is) of 1 where
    the point is not buried (_buried), else 0."""
    for p in prange(len(piece_tri)):
        stack = np.empty(STACK_SIZE, np.int32)
        nx, ny, nz = normals[p, 0], normals[p, 1], normals[p, 2]
        t = piece_tri[p]
        v0 = corners[t, 0]
        e1 = corners[t, 1] - v0
        e2 = corners[t, 2] - v0
        nrm = np.array([e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]])
        k = side_axis(nrm)
        ia, ja = (k + 1) % 3, (k + 2) % 3
        d = nrm[0] * v0[0] + nrm[1] * v0[1] + nrm[2] * v0[2]
        a11, a12, a21, a22 = e1[ia], e2[ia], e1[ja], e2[ja]
        det = a11 * a22 - a12 * a21
        total = 0.0
        cnt = 0
        q = np.empty(3)
        for si in range(samples * samples):
            if det == 0.0 or nrm[k] == 0.0:
                break
            _, _, ok = r2_point(si, piece_cell[p], origin, h, v0, nrm, k, d, a11, a12, a21, a22, det, q)
            if not ok:
                continue
            if piece_sign[p] != 0:
                g = piece_plane[p, 3]
                for a in range(3):
                    g -= piece_plane[p, a] * (q[a] - origin[a]) / h
                if g * piece_sign[p] > -1e-3:   # the other part's side, or on the cut itself (either's)
                    continue
            total += 1.0 - _buried(bvh, stack, double, mat_of, q[0], q[1], q[2], nx, ny, nz, local, near)
            cnt += 1
        if cnt == 0:
            total = 1.0 - _buried(bvh, stack, double, mat_of, centroids[p, 0], centroids[p, 1], centroids[p, 2],
                                  nx, ny, nz, local, near)
            cnt = 1
        out[p] = total / cnt


PIECE_BLOCK = 65536   # pieces per task (each piece its own: any split gives the same bits)


@dataclass(frozen=True)
class PieceShot:
    """What every block of pieces shares (sent to a worker once)."""
    bvh: object
    double: np.ndarray
    mat_of: np.ndarray
    corners: np.ndarray
    origin: np.ndarray
    h: float
    local: np.ndarray
    near: float


@dataclass(frozen=True)
class PieceBlock:
    number: int
    tri: np.ndarray
    cell: np.ndarray
    plane: np.ndarray
    sign: np.ndarray
    centroids: np.ndarray
    normals: np.ndarray

    def describe(self) -> str:
        return f"buried-piece block {self.number} ({len(self.tri):,} pieces)"


def piece_block(block: PieceBlock, shot: PieceShot) -> np.ndarray:
    """The pure task: a block's pieces' weights (buried_kernel)."""
    out = np.zeros(len(block.tri))
    buried_kernel(shot.bvh, shot.double, shot.mat_of, shot.corners, block.tri, block.cell, block.plane, block.sign,
                  block.centroids, block.normals, shot.origin, shot.h, BURIED_SAMPLES, shot.local, shot.near, out)
    return out


def piece_weights(bvh, surfaces, corners, piece_tri, piece_cell, piece_plane, piece_sign, centroids, normals, origin,
                  h: float, executor=None) -> np.ndarray:
    """(m,) weights in [BURIED_FLOOR, 1] of pieces (triangles piece_tri
    clipped to cells piece_cell of the grid (origin, h), cut by
    piece_plane on piece_sign's side, grid units; world `centroids`, unit
    side `normals`): the share of their points that are not buried.
    Blocks of PIECE_BLOCK pieces are tasks on `executor` (None: here)."""
    from ..tasks import run_tasks
    if not len(piece_tri):
        return np.zeros(0)
    a = surfaces.arrays
    shot = PieceShot(bvh.arrays, a.double_sided, a.tri_material, np.ascontiguousarray(corners, np.float64),
                     np.asarray(origin, np.float64), float(h), spiral_hemisphere(BURIED_RAYS), BURIED_REACH * h)
    tri, cell = piece_tri.astype(np.int32), piece_cell.astype(np.int64)
    plane, sign = np.ascontiguousarray(piece_plane, np.float64), np.ascontiguousarray(piece_sign, np.int8)
    cen, nrm = np.ascontiguousarray(centroids, np.float64), np.ascontiguousarray(normals, np.float64)
    blocks = [PieceBlock(j, tri[i:i + PIECE_BLOCK], cell[i:i + PIECE_BLOCK], plane[i:i + PIECE_BLOCK],
                         sign[i:i + PIECE_BLOCK], cen[i:i + PIECE_BLOCK], nrm[i:i + PIECE_BLOCK])
              for j, i in enumerate(range(0, len(tri), PIECE_BLOCK))]
    out = np.concatenate(run_tasks(executor, piece_block, blocks, shot, "pieces"))
    return np.maximum(out, BURIED_FLOOR)


def voxel_relative(weights, area, vox_of_piece, n_voxels) -> np.ndarray:
    """The weights, raised within a voxel (towards 1, in proportion) where
    they would keep less than BURIED_KEEP of its area: the weighted area is
    at least that share, so no voxel's irradiance grows more than
    1 / BURIED_KEEP times (the test is a heuristic of winding: a model
    wound inconsistently must not pour a voxel's photons onto a sliver). A
    voxel whose pieces are all buried keeps its plain area."""
    plain = np.bincount(vox_of_piece, weights=area, minlength=n_voxels)
    kept = np.bincount(vox_of_piece, weights=area * weights, minlength=n_voxels)
    short = np.maximum(BURIED_KEEP * plain - kept, 0.0)
    t = np.where(short > 0, short / np.maximum(plain - kept, 1e-300), 0.0)
    enclosed = kept <= 1.5 * BURIED_FLOOR * plain
    t = np.where(enclosed, 1.0, np.minimum(t, 1.0))[vox_of_piece]
    return weights + t * (1.0 - weights)
