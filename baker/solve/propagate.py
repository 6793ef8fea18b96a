"""Linear propagation of radiosity over a voxel set (docs/design.md section 4).

`LineSweeper` precomputes what every bounce reuses (the voxel rows, the
cut table, the three axis-major orders, the cell boundaries in each, the
table size); `gather` runs one bounce over a direction set:

    H(x) = (1 / S(n_x)) sum_{s in D, n_x.s > 0} (B(I(x, s)) / pi) (n_x.s) dW(s)

A bounce's families go out in fixed blocks of FAMILY_BLOCK of one
dominant axis (pure tasks an executor may run anywhere:
bake/executor.py); each block sums its families' gathers in family order
from zero, and the blocks' sums are added in block order: the same sums
for any thread or worker count.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import BudgetError
from ..kernels.rng import LINE_OFFSET_BOUNCE_STRIDE, STREAM_LINE_OFFSETS, rand01
from .directions import DirectionSet
from ..voxels.edges import edge_planes, footprints
from ..voxels.lookup import flat_voxels
from ..voxels.tolerances import FLAT_COS, FLAT_PLANE, SMOOTH_COS
from .records import (C_CX, C_CZ, C_D, C_NX, C_NZ, C_R, CUT, LINE, MAX_CUT_ROWS, P_CUT, P_NX, P_NZ, P_SHEET, P_X, P_Z,
                      POS, SHEET_FLAT, SHEET_KINDS)
from .sweep import HIT_BATCH, propagate_families

TAU = 0.1     # plane tolerance, in cells (docs/design.md section 4)
KAPPA = 1.0   # convex-edge reach, in cells
FAMILY_BLOCK = 16   # families per task: a multiple of the sweep's hit batch and of its two lanes


@dataclass(frozen=True)
class SweepVoxels:
    """What every block of every bounce shares: the voxel rows and the
    orders the sweep reads (LineSweeper's arrays)."""
    orders: np.ndarray
    starts: np.ndarray
    cell: np.ndarray
    cell_lo: np.ndarray
    cell_hi: np.ndarray
    pos: np.ndarray
    cutp: np.ndarray
    max_group: int


@dataclass(frozen=True)
class FamilyBlock:
    """Families of one dominant axis (their canonical vectors, unit
    vectors, weights dW / pi and line offsets), swept over the bounce's
    line table (size, hashed): one task."""
    number: int
    bounce: int
    axis: int
    vectors: np.ndarray
    units: np.ndarray
    weights: np.ndarray
    offsets: np.ndarray
    table_size: int
    hashed: bool

    def describe(self) -> str:
        return (f"direction block {self.number} of bounce {self.bounce} ({len(self.vectors)} families along axis "
                f"{'xyz'[self.axis]})")


@dataclass(frozen=True)
class FamilyPart:
    """A block's gathered sums (n, 3) and quadrature sums S (n,)."""
    gathered: np.ndarray
    quad: np.ndarray


def sweep_block(block: FamilyBlock, vox: SweepVoxels, radiosity: np.ndarray) -> FamilyPart:
    """The pure task: a block's families swept over the voxels."""
    g, q = propagate_families(vox.orders, vox.starts, vox.cell, vox.cell_lo, vox.cell_hi, vox.pos, vox.cutp,
                              radiosity, block.vectors, np.full(len(block.vectors), block.axis, np.int32),
                              block.units, block.weights, block.offsets, TAU, KAPPA, vox.max_group,
                              block.table_size, block.hashed)
    return FamilyPart(g, q)


class LineSweeper:
    def __init__(self, voxels):
        cell = np.ascontiguousarray(voxels.cell)
        n = len(cell)
        self.n = n
        self.cell = cell
        self.h = float(voxels.cell_size)
        self.origin = np.ascontiguousarray(voxels.origin, np.float64)
        # the voxel rows the sweep reads (records.py), lengths in cells
        pos = np.zeros((n, POS), np.float32)
        pos[:, P_X:P_Z + 1] = (voxels.centroid - voxels.origin) / voxels.cell_size
        pos[:, P_NX:P_NZ + 1] = voxels.normal
        flat = flat_voxels(voxels.key, voxels.cell, voxels.centroid, voxels.normal, voxels.planar, voxels.dims,
                           voxels.cell_size, SMOOTH_COS, FLAT_COS, FLAT_PLANE)
        pos[:, P_SHEET] = np.asarray(voxels.two_sided, bool) + SHEET_FLAT * flat
        cut = np.nonzero(voxels.cut_sign != 0)[0]
        # where an uncut voxel's surface ends inside its cell (voxels/edges.py), as a row after the cut rows
        edge = np.zeros((n, 4))
        edge_planes(cell, pos[:, P_X:P_Z + 1].astype(np.float64), voxels.normal.astype(np.float64),
                    np.asarray(voxels.area, np.float64) / voxels.cell_size ** 2,
                    (voxels.cut_sign == 0) & np.asarray(voxels.planar, bool), edge)
        # small pieces with no edge line: a footprint radius (voxels/edges.py), in their edge row
        has_edge = np.any(edge[:, :3] != 0, axis=1)
        foot = footprints(cell, pos[:, P_X:P_Z + 1].astype(np.float64), voxels.normal,
                          np.asarray(voxels.area, np.float64) / voxels.cell_size ** 2,
                          ~has_edge & np.asarray(voxels.planar, bool))
        edged = np.nonzero(has_edge | (foot > 0))[0]
        if len(cut) + len(edged) > MAX_CUT_ROWS:
            raise BudgetError(f"{len(cut) + len(edged)} cut and edge voxels: over the propagation's limit of "
                              f"{MAX_CUT_ROWS}; lower the resolution")
        pos[cut, P_CUT] = voxels.cut_sign[cut] * (np.arange(len(cut)) + 1.0)
        pos[edged, P_SHEET] += SHEET_KINDS * (len(cut) + np.arange(len(edged)) + 1.0)
        # the cutting planes in absolute grid coordinates (n . g = offset) and the cut voxels' cells, then the edges
        cutp = np.zeros((len(cut) + len(edged), CUT))
        cutp[:len(cut), C_NX:C_D + 1] = voxels.cut_plane[cut].astype(np.float64)
        cutp[:len(cut), C_D] += (cutp[:len(cut), C_NX:C_NZ + 1] * cell[cut]).sum(axis=1)
        cutp[:len(cut), C_CX:C_CZ + 1] = cell[cut]
        cutp[len(cut):, C_NX:C_D + 1] = edge[edged]
        cutp[len(cut):, C_CX:C_CZ + 1] = cell[edged]
        cutp[len(cut):, C_R] = foot[edged]
        self.cutp = cutp
        self._edge_rows = edged
        self._cut_rows = cut
        self.pos = pos
        # voxels come sorted by (x-major cell key, facing, sheet): cells are contiguous
        new = np.ones(n, bool)
        new[1:] = np.any(cell[1:] != cell[:-1], axis=1)
        group = np.cumsum(new) - 1
        ng = int(group[-1]) + 1 if n else 0
        orders = np.empty((3, n), np.int32)
        starts = np.empty((3, ng + 1), np.int32)
        orders[0] = np.arange(n)
        for k in (1, 2):
            k1, k2 = (k + 1) % 3, (k + 2) % 3
            orders[k] = np.lexsort((np.arange(n), cell[:, k2], cell[:, k1], cell[:, k]))
        for k in range(3):
            g = group[orders[k]]
            b = np.ones(n, bool)
            b[1:] = g[1:] != g[:-1]
            starts[k, :ng] = np.nonzero(b)[0]
            starts[k, ng] = n
        self.orders, self.starts = orders, starts
        self.max_group = int(np.diff(starts[0]).max()) if ng else 1
        self.cell_lo = cell.min(axis=0).astype(np.int64) if n else np.zeros(3, np.int64)
        self.cell_hi = cell.max(axis=0).astype(np.int64) if n else np.zeros(3, np.int64)
        self.table_size = 1 << max(10, int(np.ceil(np.log2(max(2 * ng, 2)))))

    @property
    def normal(self) -> np.ndarray:
        """(n, 3) float32 normals, as the kernel sees them."""
        return self.pos[:, P_NX:P_NZ + 1]

    @property
    def cut(self) -> np.ndarray:
        """(n, 5) float64: per voxel the plane (normal, offset n.g in grid
        coordinates) of a surface that cut its pieces and its side of it (0:
        not cut), as the kernel sees them."""
        out = np.zeros((self.n, 5))
        out[self._cut_rows, :4] = self.cutp[:len(self._cut_rows), C_NX:C_D + 1]
        out[:, 4] = np.sign(self.pos[:, P_CUT])
        return out

    @property
    def sheet(self) -> np.ndarray:
        """(n,) bool: faces of two-sided sheets, as the kernel sees them."""
        k = self.pos[:, P_SHEET] % SHEET_KINDS
        return (k == 1) | (k == 1 + SHEET_FLAT)

    @property
    def flat(self) -> np.ndarray:
        """(n,) bool: voxels on a flat stretch of surface (lookup.flat_voxels), as the kernel sees them."""
        return self.pos[:, P_SHEET] % SHEET_KINDS >= SHEET_FLAT

    @property
    def edge(self) -> np.ndarray:
        """(n, 4) float64: per voxel the half-plane of its plane where its
        surface lies inside its cell (e, t: e . g >= t, grid coordinates;
        zeros: it runs on through the cell), as the kernel sees it."""
        out = np.zeros((self.n, 4))
        out[self._edge_rows] = self.cutp[len(self._cut_rows):, C_NX:C_D + 1]
        return out

    @property
    def centroid(self) -> np.ndarray:
        """(n, 3) float64 centroids in grid coordinates, as the kernel sees them."""
        return self.pos[:, P_X:P_Z + 1].astype(np.float64)

    def line_table(self, dirs: DirectionSet):
        """(size, hashed): a dense line table as large as the largest family's
        line-id range when that stays within twice the cells (compact
        scenes), else a hashed table of a power of two >= 2 x cells (sparse
        scenes: the dense range grows with the bounding box, not the surface)."""
        ext = (self.cell_hi - self.cell_lo + 1).astype(np.int64)
        v = np.abs(dirs.vectors.astype(np.int64))
        k = dirs.axis
        a = v[np.arange(len(k)), k]
        b = v[np.arange(len(k)), (k + 1) % 3]
        c = v[np.arange(len(k)), (k + 2) % 3]
        p = (c * ext[k] + a * ext[(k + 2) % 3]) // a + 2
        q = (b * ext[k] + a * ext[(k + 1) % 3]) // a + 2
        need = int((p * q).max())
        if need >= 2 ** 31:  # line ids are int32 keys in the table
            raise BudgetError(f"the voxel grid ({(self.cell_hi - self.cell_lo + 1).tolist()} cells) is too large "
                              "for the propagation's line table (2^31 lines); lower the resolution")
        if need <= self.table_size:
            return need, False
        return self.table_size, True

    @property
    def nbytes(self) -> int:
        """Working memory of a bounce beyond the voxel arrays (the line
        tables at their largest; waiting records not counted: only the live
        ones are touched, a few per cent of the voxels)."""
        per_voxel = 4 * POS + 4 * HIT_BATCH + 24 + 8  # axis copy, hits, the outputs (gathered sums, S)
        return self.orders.nbytes + self.starts.nbytes + self.pos.nbytes + self.cutp.nbytes + \
            (12 + 2 * 4) * self.starts.shape[1] + 2 * 4 * LINE * self.table_size + self.n * per_voxel  # cells, ids

    def offsets(self, dirs: DirectionSet, seed: int, bounce: int) -> np.ndarray:
        """Seeded line offsets (mu, mu') in [0, A) per family, so that the
        discretization error of successive bounces does not line up."""
        a = dirs.vectors[np.arange(dirs.n_families), dirs.axis].astype(np.int64)
        out = np.empty((dirs.n_families, 2), np.int64)
        for f in range(dirs.n_families):
            for j in range(2):
                u = rand01(seed, bounce * LINE_OFFSET_BOUNCE_STRIDE + f, STREAM_LINE_OFFSETS + j)
                out[f, j] = int(u * a[f]) % a[f]
        return out

    def shared(self) -> SweepVoxels:
        return SweepVoxels(self.orders, self.starts, self.cell, self.cell_lo, self.cell_hi, self.pos, self.cutp,
                           self.max_group)

    def blocks(self, dirs: DirectionSet, offsets, bounce=0) -> list:
        """The bounce's families in fixed blocks: axis by axis, FAMILY_BLOCK
        at a time in the set's order."""
        size, hashed = self.line_table(dirs)
        weights = dirs.solid_angle / np.pi
        out = []
        for k in range(3):
            fams = np.nonzero(dirs.axis == k)[0]
            for f0 in range(0, len(fams), FAMILY_BLOCK):
                f = fams[f0:f0 + FAMILY_BLOCK]
                out.append(FamilyBlock(len(out), bounce, k, np.ascontiguousarray(dirs.vectors[f]),
                                       np.ascontiguousarray(dirs.unit[f]), np.ascontiguousarray(weights[f]),
                                       np.ascontiguousarray(offsets[f]), int(size), bool(hashed)))
        return out

    def gather(self, radiosity, dirs: DirectionSet, offsets, executor=None, shared=None, bounce=0):
        """(gathered (n, 3), S (n,)): sum of B(I(x, s)) (n.s) dW / pi and the
        quadrature's cosine integral per voxel, the blocks on `executor`
        (None: here; shared: its handle on self.shared())."""
        from ..startup import checkpoint
        radiosity = np.ascontiguousarray(radiosity, np.float64)
        gathered, quad = np.zeros((self.n, 3)), np.zeros(self.n)

        def fold(j, part):   # in block order: the same sums wherever the blocks ran
            np.add(gathered, part.gathered, out=gathered)
            np.add(quad, part.quad, out=quad)
        blocks = self.blocks(dirs, offsets, bounce)
        if executor is None:
            vox = self.shared()
            for j, b in enumerate(blocks):
                checkpoint()
                fold(j, sweep_block(b, vox, radiosity))
            return gathered, quad
        own = shared is None
        shared = executor.share(self.shared()) if own else shared
        light = executor.share(radiosity)
        try:
            executor.map(sweep_block, blocks, shared, light, name="families", fold=fold)
        finally:
            executor.release(light)
            if own:
                executor.release(shared)
        return gathered, quad

    def irradiance(self, radiosity, dirs: DirectionSet, offsets, executor=None, shared=None, bounce=0):
        """H (n, 3) = gathered / S, computed in place."""
        g, s = self.gather(radiosity, dirs, offsets, executor, shared, bounce)
        g /= np.where(s > 0, s, np.inf)[:, None]
        return g
