"""The gathered bounced light of a bake's texels, shaded at records spread
over the surfaces in world space and interpolated between them (an
irradiance cache on a grid).

Bounced light varies slowly: over a voxel cell, except where visibility
changes (a contact, an edge). Gathering it at every texel (or on a lattice
of every map, whose cost follows the triangle count as much as the area:
each small triangle's map brings its own lattice corners) spends most of
its rays on light that is already known. Here the points that need the
bounced light (texel points, small triangles' points) are grouped by a
world grid `spacing` apart, by the way they face (cube-map bins) and by
their clearance (how far each sees along its normal, up to CLEAR
spacings); each group is gathered once, at its member nearest the
group's mean with the group's mean normal: a record.

A point reads the records within RADIUS spacings that
- face its way (cosine at least MIN_COS) and lie on its plane (within
  PLANE spacings of it along its normal);
- are in sight of it: a segment between the two, lifted off their
  surfaces, meets nothing (no light comes through a wall);
- are in sight of it higher up too: the segment between the two each
  raised HIGH spacings, or half their clearance if lower, meets nothing
  (a floor under a low step does not read the floor beside it, whose
  hemisphere the step does not cover);
- and whose clearance agrees with its own within a factor of two (under
  a step higher than that segment).
Its value is a weighted linear fit over its tangent plane (smooth
weights; a light that changes linearly is reproduced, so neighbouring
texels differ by what the light itself changes between them). Where the
records a point reads disagree by more than `agree` of the largest plus
the point's own sharp light (a contact, a shadow of the bounced light),
or where no record qualifies, the point is gathered itself. The number
of gathers follows the surface's area in cells, not the texel density or
the triangle count."""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..kernels.bvh import STACK_SIZE
from ..kernels.colour import LUMINANCE
from ..kernels.sampling import frame
from ..kernels.traverse import any_hit, closest_hit_batch
from ..scene.topology import row_labels

RADIUS = 1.5      # spacings: a record serves points this near
MIN_COS = 0.9     # a record serves points whose normal is within about 25 degrees of its own
PLANE = 0.25      # spacings: and that lie this near its plane (curved surfaces: the sagitta over RADIUS)
HIGH = 0.5        # spacings: and that it sees from this high above each (or under what is lower: heights())
CLEAR = 2.0       # spacings: how far a point looks along its normal for what stands over it (clearance())
CLEAR_CLASSES = 4  # records of one cell whose clearances differ by a factor of 2, 4, 8 are apart
RIDGE = 1e-3     # (radii squared) added to the records' spread over the tangent plane: the slope's ridge
FACE_BINS = 4     # a cube-map face's side in bins (about 22 degrees): records of one cell facing apart
_CHUNK = 64
_BITS = 21        # per axis in a cell's key


def cube_bins(normals, bins):
    """(m,) int64: each unit normal's cell of a cube map with bins x bins
    cells a face (face major, then the two minor coordinates)."""
    m = len(normals)
    ax = np.argmax(np.abs(normals), axis=1)
    r = np.arange(m)
    major = normals[r, ax]
    minor = np.stack([normals[r, (ax + 1) % 3], normals[r, (ax + 2) % 3]], axis=1) / np.abs(major)[:, None]
    q = np.clip(np.floor((minor + 1.0) * (0.5 * bins)), 0, bins - 1).astype(np.int64)
    return (2 * ax + (major > 0)) * bins * bins + q[:, 0] * bins + q[:, 1]


def representatives(points, normals, key):
    """Groups of points (m, 3) by key (m, j) int64: (rep (k,), of (m,),
    normal (k, 3)): each group's member nearest the members' mean (a
    point on the surface: the mean of a curved patch's points lies under
    it), ties to the first, each point's group, and the members' mean
    unit normal; groups in key order."""
    m = len(points)
    if not m:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3))
    of = row_labels(key)
    k = int(of.max()) + 1
    count = np.bincount(of, minlength=k)
    mean = np.stack([np.bincount(of, weights=points[:, c], minlength=k) for c in range(3)], axis=1) / count[:, None]
    normal = np.stack([np.bincount(of, weights=normals[:, c], minlength=k) for c in range(3)], axis=1)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    dist = np.linalg.norm(points - mean[of], axis=1)
    order = np.lexsort((np.arange(m), dist, of))   # by group, then distance, then index
    first = np.ones(m, bool)
    first[1:] = of[order[1:]] != of[order[:-1]]
    return order[first], of, normal


def record_keys(points, normals, spacing, clear):
    """(m, 2) int64 group key of each point: its grid cell, and its cube-map
    bin with its clearance's class (clear (m,): clearance(); a factor of
    two apart per class, CLEAR_CLASSES of them)."""
    if not len(points):
        return np.zeros((0, 2), np.int64)
    facing = cube_bins(normals, FACE_BINS)
    top = CLEAR * spacing
    cls = np.clip(np.floor(np.log2(top / np.maximum(clear, 1e-300 * top))), 0, CLEAR_CLASSES - 1).astype(np.int64)
    return np.column_stack([cell_keys(points, spacing), cls * 6 * FACE_BINS * FACE_BINS + facing])


def clearance(bvh, points, normals, spacing, lift):
    """(n,) how far each point (unit normals) sees along its normal from
    the lift, up to CLEAR spacings (what stands over a floor: a step, a
    table)."""
    if not len(points):
        return np.zeros(0)
    top = CLEAR * spacing
    t, _, _, _ = closest_hit_batch(bvh, np.ascontiguousarray(points + lift * normals, np.float64),
                                   np.ascontiguousarray(normals, np.float64), 0.0, np.full(len(points), top))
    return np.minimum(t + lift, top)


def cell_keys(points, spacing):
    """(m,) int64: each point's grid cell, packed (21 bits an axis, offset
    so that any finite scene within 2^20 cells of the origin fits)."""
    c = np.floor(np.asarray(points, np.float64) / float(spacing)).astype(np.int64) + (1 << (_BITS - 1))
    c = np.clip(c, 0, (1 << _BITS) - 1)
    return (c[:, 0] << (2 * _BITS)) | (c[:, 1] << _BITS) | c[:, 2]


def records(points, normals, spacing, clear):
    """(rep (k,) int64, normal (k, 3)): each group's (record_keys) member
    nearest the group's mean and the group's mean unit normal
    (representatives; a cube-map bin holds no opposite normals, so the
    mean is never near zero)."""
    rep, _, normal = representatives(points, normals, record_keys(points, normals, spacing, clear))
    return rep, normal


@njit(cache=True, parallel=True, error_model="numpy")
def interpolate_kernel(bvh, rpoint, rnormal, rclear, rheight, rlum, rvalue, rkey, points, normals, clear, height,
                       spacing, lift, out, weight, spread):
    """For each point: out (n, 3) the records that serve it (module
    docstring) fitted by weighted least squares with a linear function
    over the point's tangent plane (the value at the point; a ridge RIDGE
    on the slope keeps records along a line well posed) and clamped to
    the records' own range (no overshoot: finite, non-negative); weight
    (n,) their weights' sum (0: none); spread (n, 2) the smallest and
    largest luminance among them. Records sorted by rkey, their grid
    cell's key; clear, rclear: the points' and records' clearances
    (clearance(): those a factor of two apart do not share); height,
    rheight: their heights (heights())."""
    n = points.shape[0]
    radius = RADIUS * spacing
    plane = PLANE * spacing
    half = 1 << (_BITS - 1)
    top = (1 << _BITS) - 1
    for ch in prange((n + _CHUNK - 1) // _CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        s1 = np.zeros(6)       # sums of w, w u, w v, w u u, w u v, w v v
        sf = np.zeros((3, 3))  # per channel: sums of w f, w f u, w f v
        lo_c = np.zeros(3)
        hi_c = np.zeros(3)
        for i in range(ch * _CHUNK, min(n, (ch + 1) * _CHUNK)):
            px, py, pz = points[i, 0], points[i, 1], points[i, 2]
            nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
            (tx, ty, tz), (bx_, by_, bz_) = frame(nx, ny, nz)
            ax, ay, az = px + lift * nx, py + lift * ny, pz + lift * nz
            qh = height[i]
            cx = int(np.floor(px / spacing)) + half
            cy = int(np.floor(py / spacing)) + half
            cz = int(np.floor(pz / spacing)) + half
            s1[:] = 0.0
            sf[:, :] = 0.0
            lo_c[:] = np.inf
            hi_c[:] = -np.inf
            lo = np.inf
            hi = -np.inf
            for dx in range(-1, 2):
                for dy in range(-1, 2):
                    for dz in range(-1, 2):
                        x, y, z = cx + dx, cy + dy, cz + dz
                        if x < 0 or y < 0 or z < 0 or x > top or y > top or z > top:
                            continue
                        key = (x << (2 * _BITS)) | (y << _BITS) | z
                        a = np.searchsorted(rkey, key)
                        while a < rkey.shape[0] and rkey[a] == key:
                            r = a
                            a += 1
                            ex, ey, ez = rpoint[r, 0] - px, rpoint[r, 1] - py, rpoint[r, 2] - pz
                            d2 = ex * ex + ey * ey + ez * ez
                            if d2 >= radius * radius:
                                continue
                            cos = nx * rnormal[r, 0] + ny * rnormal[r, 1] + nz * rnormal[r, 2]
                            if cos < MIN_COS:
                                continue
                            if abs(ex * nx + ey * ny + ez * nz) > plane:
                                continue
                            if max(clear[i], rclear[r]) > 2.0 * min(clear[i], rclear[r]):
                                continue
                            gx = rpoint[r, 0] + lift * rnormal[r, 0] - ax
                            gy = rpoint[r, 1] + lift * rnormal[r, 1] - ay
                            gz = rpoint[r, 2] + lift * rnormal[r, 2] - az
                            dist = np.sqrt(gx * gx + gy * gy + gz * gz)
                            if dist > 1e-12 * spacing and any_hit(bvh, stack, ax, ay, az, gx / dist, gy / dist,
                                                                  gz / dist, 0.0, dist):
                                continue
                            # and each at its own height: a point under a low overhang (a step above the
                            # floor) and one beside it see each other at the lift, not the same hemisphere
                            hx, hy, hz = px + qh * nx, py + qh * ny, pz + qh * nz
                            gx = rpoint[r, 0] + rheight[r] * rnormal[r, 0] - hx
                            gy = rpoint[r, 1] + rheight[r] * rnormal[r, 1] - hy
                            gz = rpoint[r, 2] + rheight[r] * rnormal[r, 2] - hz
                            dist = np.sqrt(gx * gx + gy * gy + gz * gz)
                            if dist > 1e-12 * spacing and any_hit(bvh, stack, hx, hy, hz, gx / dist, gy / dist,
                                                                  gz / dist, 0.0, dist):
                                continue
                            q = 1.0 - d2 / (radius * radius)
                            w = q * q * (cos - MIN_COS) / (1.0 - MIN_COS)
                            if w <= 0.0:
                                continue
                            u = (ex * tx + ey * ty + ez * tz) / radius
                            v = (ex * bx_ + ey * by_ + ez * bz_) / radius
                            s1[0] += w
                            s1[1] += w * u
                            s1[2] += w * v
                            s1[3] += w * u * u
                            s1[4] += w * u * v
                            s1[5] += w * v * v
                            for c in range(3):
                                f = rvalue[r, c]
                                sf[c, 0] += w * f
                                sf[c, 1] += w * f * u
                                sf[c, 2] += w * f * v
                                lo_c[c] = min(lo_c[c], f)
                                hi_c[c] = max(hi_c[c], f)
                            lo = min(lo, rlum[r])
                            hi = max(hi, rlum[r])
            wsum = s1[0]
            weight[i] = wsum
            if wsum > 0.0:
                mu, mv = s1[1] / wsum, s1[2] / wsum
                cuu = s1[3] / wsum - mu * mu + RIDGE
                cuv = s1[4] / wsum - mu * mv
                cvv = s1[5] / wsum - mv * mv + RIDGE
                det = cuu * cvv - cuv * cuv
                for c in range(3):
                    mf = sf[c, 0] / wsum
                    fu = sf[c, 1] / wsum - mu * mf
                    fv = sf[c, 2] / wsum - mv * mf
                    gu = (cvv * fu - cuv * fv) / det
                    gv = (cuu * fv - cuv * fu) / det
                    out[i, c] = min(max(mf - gu * mu - gv * mv, lo_c[c]), hi_c[c])
                spread[i, 0] = lo
                spread[i, 1] = hi


def heights(clear, spacing, lift):
    """(n,) how high above each point its second visibility segment runs:
    HIGH spacings, or half its clearance if that is lower (never below
    the lift)."""
    return np.maximum(np.minimum(HIGH * spacing, 0.5 * clear), lift)


def interpolate(bvh, rpoint, rnormal, rclear, rvalue, points, normals, clear, spacing, lift):
    """(values (n, 3), weight (n,), spread (n, 2)) at points (unit normals,
    clearances clear) from records at rpoint with rnormal, rclear and
    rvalue (interpolate_kernel)."""
    n = len(points)
    out, weight, spread = np.zeros((n, 3)), np.zeros(n), np.zeros((n, 2))
    if n and len(rpoint):
        rkey = cell_keys(rpoint, spacing)
        order = np.argsort(rkey, kind="stable")
        rp = np.ascontiguousarray(rpoint[order], np.float64)
        rn = np.ascontiguousarray(rnormal[order], np.float64)
        rv = np.ascontiguousarray(rvalue[order], np.float64)
        rc = np.ascontiguousarray(rclear[order], np.float64)
        clear = np.ascontiguousarray(clear, np.float64)
        interpolate_kernel(bvh, rp, rn, rc, heights(rc, spacing, lift), np.ascontiguousarray(rv @ LUMINANCE), rv,
                           np.ascontiguousarray(rkey[order]), np.ascontiguousarray(points, np.float64),
                           np.ascontiguousarray(normals, np.float64), clear, heights(clear, spacing, lift),
                           float(spacing), float(lift), out, weight, spread)
    return out, weight, spread


class SmoothCache:
    """The gathered light of a set of points (n, 3) with unit normals, by
    `gather(points, normals) -> (m, 3)` at records `spacing` apart and
    interpolated (module docstring). values: (n, 3) the light at each
    point; own: (n,) bool, the points gathered themselves; gathered: the
    points gathered in all (records and own)."""

    def __init__(self, bvh, gather, points, normals, spacing, lift):
        self.bvh, self.gather, self.spacing, self.lift = bvh, gather, float(spacing), float(lift)
        self.points, self.normals = np.asarray(points, np.float64), np.asarray(normals, np.float64)
        clear = clearance(bvh, self.points, self.normals, self.spacing, self.lift)
        rep, rnormal = records(self.points, self.normals, self.spacing, clear)
        self.rpoint = self.points[rep]
        self.rvalue = gather(self.rpoint, rnormal) if len(rep) else np.zeros((0, 3))
        self.values, weight, self.spread = interpolate(bvh, self.rpoint, rnormal, clear[rep], self.rvalue,
                                                       self.points, self.normals, clear, self.spacing, self.lift)
        self.own = weight <= 0.0
        self.gathered = len(rep)
        self._gather_own(np.nonzero(self.own)[0])

    def _gather_own(self, idx):
        if len(idx):
            self.values[idx] = self.gather(self.points[idx], self.normals[idx])
            self.gathered += len(idx)

    def refine(self, sharp_lum, agree):
        """Points whose records spread by more than `agree` of the largest
        plus the point's sharp light (luminance (n,)) are gathered
        themselves; returns how many."""
        lo, hi = self.spread[:, 0], self.spread[:, 1]
        bad = np.nonzero(~self.own & (hi - lo > agree * (hi + np.asarray(sharp_lum))))[0]
        self._gather_own(bad)
        self.own[bad] = True
        return len(bad)
