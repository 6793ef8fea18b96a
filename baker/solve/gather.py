"""Final gathers into the voxel solution (docs/design.md sections 5 and
8): K rays over a point's hemisphere, cosine-distributed, each reading the
outgoing radiosity B of the voxel it hits (on the side it hits). Then

    H(p) = integral of L cos dw  ~=  (pi / K) sum_k B(hit_k) / pi = mean_k B(hit_k)

Two users. The solver's bounces after the photons (`gather_voxels`): the
irradiance each voxel receives from the light that bounced last, gathered
at the voxel's centroid, the cache method's "propagate only what newly
arrived" by rays instead of digital lines (gather_rays > 0). And the
lightmap's bounced light (`gather_bounced`): B_ind, the solution's
radiosity less emission (the emitters' own light is the sharp part's), at
the texels' smooth lattice.

The directions are one fixed stratified set (a Fibonacci spiral on the
unit disk lifted onto the hemisphere, Malley's method), turned into each
point's frame: points of one plane take the same world directions, so
the estimate's error varies smoothly along a surface instead of as noise,
and it is the same for any thread count.

A ray that hits the back of a one-sided surface, or a voxel facing away
from it, reads nothing (a two-sided sheet's voxel emits on its normal's
side, as its VPL does); through thin glass it reads the pane's voxel and
goes on, tinted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..kernels.bvh import PASS_GLASS, STACK_SIZE
from ..kernels.sampling import spiral_hemisphere
from ..kernels.traverse import any_hit, closest_hit, hit_normal
from ..voxels.lookup import voxel_of_hit
from ..voxels.tolerances import SHEET_BACK_COS, SKIN_COS

GLASS_LAYERS = 8   # panes a gather ray crosses before it stops (a window's two faces, a display case)
GATHER_FLOOR = 64   # rays per voxel below which a later bounce's gather does not halve
VOXEL_BLOCKS = 4        # tasks per worker for each of the solver's gathers (a voxel's value is its own: any split
VOXEL_BLOCK_MIN = 1024  # gives the same bits), each of at least this many voxels; in this process, one task
VOXEL_LIFT = 0.25   # cells: a voxel's gather rays start this far off its centroid, along its normal
VOXEL_GAP = 0.3     # cells: two voxels facing each other closer than this pass no light by the solver's gather. Such
#                     a gap (a lamp 1 cm under a ceiling) is thinner than a voxel: the ceiling's voxel over the lamp's
#                     edge is one value for the gap and the room beside it, so light bounced to and fro in the gap
#                     (2.3x the lamp's own there) would reach the room through it; the lines pass none either


def gather_directions(k: int) -> np.ndarray:
    """k cosine-distributed unit directions about +z (k, 3)."""
    return spiral_hemisphere(k)


@njit(cache=True, inline="always")
def _frame(nx, ny, nz):
    if abs(nx) < 0.9:
        ax, ay, az = 1.0, 0.0, 0.0
    else:
        ax, ay, az = 0.0, 1.0, 0.0
    tx, ty, tz = ay * nz - az * ny, az * nx - ax * nz, ax * ny - ay * nx
    tl = math.sqrt(tx * tx + ty * ty + tz * tz)
    tx, ty, tz = tx / tl, ty / tl, tz / tl
    return tx, ty, tz, ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx


@njit(cache=True)
def _sees(bvh, stack, vnormal, vcentroid, vi, px, py, pz, dx, dy, dz, h):
    """Whether the hit point p (reached along d) and voxel vi's centroid
    see each other. Asked only of a voxel whose pieces another surface cut:
    one plane splits a cell, and in a corner, where two walls meet, the
    part on p's side of the one can still reach round the other, into a
    room its light never enters."""
    e = 0.01 * h
    lift = VOXEL_LIFT * h   # off the voxel's own surface, which a curved voxel's centroid lies under
    sx, sy, sz = px - e * dx, py - e * dy, pz - e * dz
    tx = vcentroid[vi, 0] + lift * vnormal[vi, 0] - sx
    ty = vcentroid[vi, 1] + lift * vnormal[vi, 1] - sy
    tz = vcentroid[vi, 2] + lift * vnormal[vi, 2] - sz
    dist = math.sqrt(tx * tx + ty * ty + tz * tz)
    if dist <= e:
        return True
    return not any_hit(bvh, stack, sx, sy, sz, tx / dist, ty / dist, tz / dist, 0.0, dist)


@njit(cache=True)
def _voxel_origin(bvh, stack, double, mat_of, planar, cx, cy, cz, nx, ny, nz, lift):
    """Where a voxel's gather rays start: `lift` along its normal from its
    centroid, or halfway to a surface met first (a ceiling's voxel 1 cm
    above a lamp must not start under the lamp, in the room). A curved
    voxel's centroid lies under its surface by the sagitta of its patch:
    unless the voxel is planar, a surface met from behind (its normal
    within 60 degrees of the voxel's, as lights.vpl.on_surface) is its
    skin, and the lift starts there."""
    base = 0.0
    tmin = 1e-3 * lift   # not the voxel's own plane, met at rounding distance
    for _ in range(4):
        t, j, u, v = closest_hit(bvh, stack, cx, cy, cz, nx, ny, nz, base + tmin, base + lift)
        if j < 0:
            break
        hx, hy, hz = hit_normal(bvh, j)
        c = hx * nx + hy * ny + hz * nz
        if not planar and (c > SKIN_COS or (double[mat_of[bvh.tri_index[j]]] and -c > SKIN_COS)):
            base = t + 1e-4 * lift
            continue
        lift = 0.5 * (t - base)
        break
    return cx + (base + lift) * nx, cy + (base + lift) * ny, cz + (base + lift) * nz


GAP_STOP = -2   # _read_at: the ray met a voxel facing it across a gap thinner than VOXEL_GAP, and stops


@njit(cache=True, inline="always")
def _read_at(bvh, stack, double, mat_of, vnormal, vcentroid, vcut, pieces, gap, nx, ny, nz, ox, oy, oz, dx, dy, dz,
             t, j):
    """The voxel a gather ray (from o along d, its point's normal n) that
    hit BVH triangle j at t reads: -1 none (the back of a one-sided
    surface, a voxel facing away, a cut voxel that does not see the hit),
    GAP_STOP where it must stop there (see VOXEL_GAP)."""
    hx, hy, hz = hit_normal(bvh, j)
    tri = bvh.tri_index[j]
    back = hx * dx + hy * dy + hz * dz > 0.0
    if back and not double[mat_of[tri]]:
        return -1
    px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
    vi = voxel_of_hit(tri, back, px, py, pz, pieces)
    if vi < 0:
        return -1
    if t < gap and vnormal[vi, 0] * nx + vnormal[vi, 1] * ny + vnormal[vi, 2] * nz < SHEET_BACK_COS:
        return GAP_STOP
    if vnormal[vi, 0] * dx + vnormal[vi, 1] * dy + vnormal[vi, 2] * dz < 0.0 \
            and (vcut[vi] == 0 or _sees(bvh, stack, vnormal, vcentroid, vi, px, py, pz, dx, dy, dz, pieces.h)):
        return vi
    return -1


@njit(cache=True, parallel=True, error_model="numpy")
def gather_kernel(bvh, double, mat_of, b_ind, vnormal, vcentroid, vcut, vplanar, pieces, points, normals, own, offset,
                  gap, local, out):
    """out[i] (3,) the gathered irradiance at points[i] (normal
    normals[i], rays from offset along it) over the directions `local`.
    vcentroid, vcut, vplanar: the voxels' centroids, cut signs
    (Voxels.cut_sign) and planarity; own[i] >= 0: points[i] is that
    voxel's centroid, and its rays start at _voxel_origin (offset at
    most); -1: at offset. A voxel facing the point's normal (within 25
    degrees) and hit closer than `gap` is not read (see VOXEL_GAP)."""
    n = len(points)
    k_n = len(local)
    for i in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        tx, ty, tz, bx, by, bz = _frame(nx, ny, nz)
        if own[i] >= 0:
            ox0, oy0, oz0 = _voxel_origin(bvh, stack, double, mat_of, vplanar[own[i]], points[i, 0], points[i, 1],
                                          points[i, 2], nx, ny, nz, offset)
        else:
            ox0, oy0, oz0 = points[i, 0] + offset * nx, points[i, 1] + offset * ny, points[i, 2] + offset * nz
        a0 = a1 = a2 = 0.0
        for k in range(k_n):
            lx, ly, lz = local[k, 0], local[k, 1], local[k, 2]
            dx = lx * tx + ly * bx + lz * nx
            dy = lx * ty + ly * by + lz * ny
            dz = lx * tz + ly * bz + lz * nz
            ox, oy, oz = ox0, oy0, oz0
            w0 = w1 = w2 = 1.0
            for _layer in range(GLASS_LAYERS):
                t, j, u, v = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
                if j < 0:   # the sky's light is the sky's cut's (lights.sky_light)
                    break
                vi = _read_at(bvh, stack, double, mat_of, vnormal, vcentroid, vcut, pieces, gap, nx, ny, nz, ox, oy,
                              oz, dx, dy, dz, t, j)
                if vi == GAP_STOP:
                    break
                if vi >= 0:
                    a0 += w0 * b_ind[vi, 0]
                    a1 += w1 * b_ind[vi, 1]
                    a2 += w2 * b_ind[vi, 2]
                if bvh.tri_pass[j] != PASS_GLASS:
                    break
                g = bvh.glass_tint[bvh.tri_mat[j]]
                w0, w1, w2 = w0 * g[0], w1 * g[1], w2 * g[2]
                if w0 <= 0.0 and w1 <= 0.0 and w2 <= 0.0:
                    break
                step = 1e-6 * max(1.0, t)   # past the pane, not onto it again
                ox, oy, oz = ox + t * dx + step * dx, oy + t * dy + step * dy, oz + t * dz + step * dz
        out[i, 0] = a0 / k_n
        out[i, 1] = a1 / k_n
        out[i, 2] = a2 / k_n


def rays_for_bounce(rays: int, k: int) -> int:
    """Gather rays per voxel at bounce k >= 2 (the photons' is 1): `rays`
    at the first gathered bounce, halved at each one after (the newly
    arrived light gets smoother bounce by bounce, as the cache method's
    direction sets halve), down to GATHER_FLOOR (or `rays`, if fewer)."""
    return max(min(rays, GATHER_FLOOR), rays >> min(k - 2, 30))


@dataclass(frozen=True)
class GatherVoxels:
    """What every block of the solver's gathers shares: the kernels' BVH
    arrays and materials, the voxels' normals, centroids, cut signs,
    planarity and lookup, the rays' lift and the facing gap (lengths)."""
    bvh: object
    double: np.ndarray
    mat_of: np.ndarray
    normal: np.ndarray
    centroid: np.ndarray
    cut: np.ndarray
    planar: np.ndarray
    pieces: object
    lift: float
    gap: float

    @classmethod
    def of(cls, prepared, vox):
        a = prepared.surfaces.arrays
        return cls(prepared.bvh.arrays, a.double_sided, a.tri_material, np.ascontiguousarray(vox.normal, np.float64),
                   np.ascontiguousarray(vox.centroid, np.float64), vox.cut_sign, vox.planar, vox.lookup(),
                   VOXEL_LIFT * vox.cell_size, VOXEL_GAP * vox.cell_size)


@dataclass(frozen=True)
class VoxelBlock:
    """Voxels start .. stop - 1 (or, with `own`, those voxels), gathered
    by `rays` rays at bounce `bounce` ("targets": their rays' voxels
    recorded instead): one task."""
    number: int
    bounce: int
    start: int
    stop: int
    rays: int
    targets: bool = False
    own: np.ndarray | None = None

    def voxels(self) -> np.ndarray:
        return self.own if self.own is not None else np.arange(self.start, self.stop, dtype=np.int64)

    def describe(self) -> str:
        what = "the rays' voxels" if self.targets else "gather"
        return f"voxel block {self.number} of bounce {self.bounce} ({what}, {len(self.voxels()):,} voxels)"


def gather_block(block: VoxelBlock, g: GatherVoxels, radiosity=None):
    """The pure task: (m, 3) the block's gathered irradiance, or (targets
    (m, k) int32, live (m,) bool) for a targets block."""
    own = block.voxels()
    local = gather_directions(int(block.rays))
    args = (g.bvh, g.double, g.mat_of)
    if block.targets:
        target = np.empty((len(own), len(local)), np.int32)
        live = np.zeros(len(own), bool)
        gather_targets(*args, g.normal, g.centroid, g.cut, g.planar, g.pieces, own, g.lift, g.gap, local, target,
                       live)
        return target, live
    out = np.zeros((len(own), 3))
    gather_kernel(*args, radiosity, g.normal, g.centroid, g.cut, g.planar, g.pieces, g.centroid[own], g.normal[own],
                  own, g.lift, g.gap, local, out)
    return out


def _block_size(n, executor):
    workers = getattr(executor, "workers", 0)
    return max(n, 1) if not workers else max(VOXEL_BLOCK_MIN, -(-n // (VOXEL_BLOCKS * workers)))


def _blocks(n, size, rays, bounce, targets=False):
    return [VoxelBlock(j, bounce, a, min(n, a + size), int(rays), targets) for j, a in enumerate(range(0, n, size))]


def _own_blocks(own, size, rays, bounce):
    return [VoxelBlock(j, bounce, 0, 0, int(rays), False, own[a:a + size])
            for j, a in enumerate(range(0, len(own), size))]


def gather_voxels(prepared, vox, radiosity, rays, cache=None, executor=None, shared=None, bounce=0) -> np.ndarray:
    """(n, 3) float64: the irradiance at each voxel (its centroid, lifted
    VOXEL_LIFT cells along its normal) gathered by `rays` rays from the
    voxels' radiosity (n, 3). cache: a dict kept across bounces; the
    bounces that take GATHER_FLOOR rays (all but the first two) cast the
    same rays from the same points, so the first of them records the
    voxel each ray reads (GatherTargets) and the others only read them.
    The voxels go out in blocks on `executor` (None: here; shared: its
    handle on GatherVoxels.of(prepared, vox)), VOXEL_BLOCKS per worker; a
    voxel's value depends on nothing else, so the split changes no bit."""
    from ..startup import checkpoint
    n = len(vox)
    out = np.zeros((n, 3))
    if not n:
        return out
    radiosity = np.ascontiguousarray(radiosity, np.float64)
    g = GatherVoxels.of(prepared, vox) if shared is None else None
    size = _block_size(n, executor)

    def run(blocks, light=None):
        """The blocks' results, in order."""
        if executor is None:
            res = []
            for b in blocks:
                checkpoint()
                res.append(gather_block(b, g, light) if light is not None else gather_block(b, g))
            return res
        handle = shared if shared is not None else executor.share(g)
        lit = executor.share(light) if light is not None else None
        try:
            return executor.map(gather_block, blocks, handle, *(() if lit is None else (lit,)), name="voxels")
        finally:
            executor.release(lit)
            if shared is None:
                executor.release(handle)
    if cache is None or int(rays) > GATHER_FLOOR:
        blocks = _blocks(n, size, rays, bounce)
        for b, r in zip(blocks, run(blocks, radiosity)):
            out[b.start:b.stop] = r
        return out
    if int(rays) not in cache:
        blocks = _blocks(n, size, rays, bounce, targets=True)
        parts = run(blocks)
        target = np.concatenate([t for t, _ in parts])
        live = np.concatenate([lv for _, lv in parts])
        cache[int(rays)] = (target, np.nonzero(live)[0])
    target, live = cache[int(rays)]
    gather_read(target, radiosity, out)
    if len(live):   # voxels with a ray through glass: traced afresh (their rays read several voxels, tinted)
        blocks = _own_blocks(live.astype(np.int64), size, rays, bounce)
        out[live] = np.concatenate(run(blocks, radiosity))
    return out


@njit(cache=True, parallel=True, error_model="numpy")
def gather_targets(bvh, double, mat_of, vnormal, vcentroid, vcut, vplanar, pieces, own, offset, gap, local, target,
                   live):
    """What gather_kernel's rays from the voxels `own` read, without
    reading it: target[i, k] the voxel ray k of own[i] reads (-1: none);
    live[i] where one of its rays meets glass first (it reads the pane
    and goes on, tinted: gather_kernel traces it at each bounce). The
    same rays and tests as gather_kernel (_read_at)."""
    n = len(own)
    k_n = len(local)
    for i in prange(n):
        stack = np.empty(STACK_SIZE, np.int32)
        vo = own[i]
        nx, ny, nz = vnormal[vo, 0], vnormal[vo, 1], vnormal[vo, 2]
        tx, ty, tz, bx, by, bz = _frame(nx, ny, nz)
        ox, oy, oz = _voxel_origin(bvh, stack, double, mat_of, vplanar[vo], vcentroid[vo, 0], vcentroid[vo, 1],
                                   vcentroid[vo, 2], nx, ny, nz, offset)
        for k in range(k_n):
            target[i, k] = -1
        for k in range(k_n):
            lx, ly, lz = local[k, 0], local[k, 1], local[k, 2]
            dx = lx * tx + ly * bx + lz * nx
            dy = lx * ty + ly * by + lz * ny
            dz = lx * tz + ly * bz + lz * nz
            t, j, u, v = closest_hit(bvh, stack, ox, oy, oz, dx, dy, dz, 0.0, np.inf)
            if j < 0:
                continue
            if bvh.tri_pass[j] == PASS_GLASS:
                live[i] = True
                break
            target[i, k] = max(-1, _read_at(bvh, stack, double, mat_of, vnormal, vcentroid, vcut, pieces, gap, nx,
                                            ny, nz, ox, oy, oz, dx, dy, dz, t, j))


@njit(cache=True, parallel=True)
def gather_read(target, b, out):
    """out[i] = the mean over k of b[target[i, k]] (-1: 0), summed in k's
    order as gather_kernel sums (the same bits)."""
    k_n = target.shape[1]
    for i in prange(target.shape[0]):
        a0 = a1 = a2 = 0.0
        for k in range(k_n):
            vi = target[i, k]
            if vi >= 0:
                a0 += 1.0 * b[vi, 0]
                a1 += 1.0 * b[vi, 1]
                a2 += 1.0 * b[vi, 2]
        out[i, 0] = a0 / k_n
        out[i, 1] = a1 / k_n
        out[i, 2] = a2 / k_n


def gather_bounced(prepared, solution, points, normals, offset, rays) -> np.ndarray:
    """(N, 3) float64: the bounced light at points (unit normals, the side
    that receives) gathered from the voxel solution by `rays` rays each."""
    a = prepared.surfaces.arrays
    v = solution.voxels
    b_ind = np.ascontiguousarray(np.maximum(solution.radiosity - v.emission, 0.0), np.float64)
    out = np.zeros((len(points), 3))
    if len(points):
        gather_kernel(prepared.bvh.arrays, a.double_sided, a.tri_material, b_ind,
                      np.ascontiguousarray(v.normal, np.float64), np.ascontiguousarray(v.centroid, np.float64),
                      v.cut_sign, v.planar, v.lookup(),
                      np.ascontiguousarray(points, np.float64), np.ascontiguousarray(normals, np.float64),
                      np.full(len(points), -1, np.int64), float(offset), 0.0, gather_directions(int(rays)), out)
    return out
