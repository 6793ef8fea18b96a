"""What a scene's geometry holds that the voxel method handles only in part
(docs/design.md section 2, "Which geometry is handled how"), for the
audit (`voxbake audit`) to report:

- duplicate triangles the loader dropped (the same corners in the same
  winding: one surface counts once);
- coplanar triangles that overlap in part, facing the same way (each
  counts in the voxels' area: their overlap is lit twice);
- two-sided emitters (both faces emit: a lamp read from OBJ);
- closed (or nearly closed) two-sided shells (a scanned model read from
  PLY or OBJ): both
  faces are solved, the inner ones dark; where the shell is thinner than
  a cell or noisy its faces lie a cell apart or less, and the propagation
  keeps them apart by the own-back rules (docs/design.md section 4).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .topology import triangle_adjacency


@dataclass(frozen=True)
class GeometryReport:
    triangles: int
    duplicates_dropped: int
    overlapping_pairs: int        # coplanar pairs facing the same way that overlap
    overlap_area: float           # their overlapping area, scene units^2
    area: float                   # the scene's triangle area, scene units^2
    two_sided_shells: int         # closed (or nearly) components of two-sided triangles
    two_sided_shell_triangles: int
    two_sided_emitters: int = 0   # emitting triangles whose back emits too

    def summary(self) -> str:
        lines = [f"geometry: {self.triangles} triangles, area {self.area:.4g}"]
        if self.duplicates_dropped:
            lines.append(f"  {self.duplicates_dropped} duplicate triangles dropped when loading (counted once)")
        if self.overlapping_pairs:
            lines.append(f"  {self.overlapping_pairs} pairs of coplanar triangles overlap facing the same way: "
                         f"{self.overlap_area:.4g} ({100 * self.overlap_area / max(self.area, 1e-300):.2f}% of the "
                         f"area) counts twice in the voxels (remove the duplicated part of the mesh)")
        if self.two_sided_shells:
            lines.append(f"  {self.two_sided_shells} closed (or nearly closed) two-sided shells "
                         f"({self.two_sided_shell_triangles} "
                         f"triangles): their inside faces are solved too; if the model's normals point out, "
                         f"--one-sided solves only the outside (half the voxels)")
        if self.two_sided_emitters:
            lines.append(f"  {self.two_sided_emitters} emitting triangles are two-sided: both faces emit (an OBJ lamp "
                         f"emits up into the ceiling too); within a cell of another surface that light is trapped in "
                         f"the voxels, while it leaks out of the gap in reality: make the lamp one-sided "
                         f"(--one-sided, or a glTF material without doubleSided) if only its front should emit")
        if len(lines) == 1:
            lines.append("  no duplicates, overlapping coplanar faces, closed two-sided shells or two-sided lamps")
        return "\n".join(lines)


def _count_dropped(scene) -> int:
    for note in scene.warnings:
        if "duplicate triangle" in note and "dropped" in note:
            words = note.split("dropped", 1)[1].split()
            if words and words[0].isdigit():
                return int(words[0])
    return 0


@njit(cache=True)
def _clip(px, py, m, ax, ay, bx, by, cx, cy):
    """Polygon (px, py)[:m] clipped to the counter-clockwise triangle abc."""
    ex = (ax, bx, cx)
    ey = (ay, by, cy)
    for k in range(3):
        x0, y0 = ex[k], ey[k]
        x1, y1 = ex[(k + 1) % 3], ey[(k + 1) % 3]
        qx = np.empty(m + 3)
        qy = np.empty(m + 3)
        n = 0
        for i in range(m):
            j = (i + 1) % m
            si = (x1 - x0) * (py[i] - y0) - (y1 - y0) * (px[i] - x0)
            sj = (x1 - x0) * (py[j] - y0) - (y1 - y0) * (px[j] - x0)
            if si >= 0:
                qx[n] = px[i]
                qy[n] = py[i]
                n += 1
            if (si >= 0) != (sj >= 0):
                t = si / (si - sj)
                qx[n] = px[i] + t * (px[j] - px[i])
                qy[n] = py[i] + t * (py[j] - py[i])
                n += 1
        px, py, m = qx, qy, n
        if m == 0:
            break
    return px, py, m


@njit(cache=True)
def _overlaps(uv, groups, starts, min_frac):
    """Overlapping pairs within each group of coplanar same-facing triangles
    (uv (nt, 3, 2) projected corners, counter-clockwise): (pairs, area)."""
    pairs = 0
    total = 0.0
    for g in range(starts.shape[0] - 1):
        a, b = starts[g], starts[g + 1]
        for i in range(a, b):
            ti = groups[i]
            for j in range(i + 1, b):
                tj = groups[j]
                if max(uv[ti, 0, 0], uv[ti, 1, 0], uv[ti, 2, 0]) <= min(uv[tj, 0, 0], uv[tj, 1, 0], uv[tj, 2, 0]) or \
                        max(uv[tj, 0, 0], uv[tj, 1, 0], uv[tj, 2, 0]) <= min(uv[ti, 0, 0], uv[ti, 1, 0], uv[ti, 2, 0]) or \
                        max(uv[ti, 0, 1], uv[ti, 1, 1], uv[ti, 2, 1]) <= min(uv[tj, 0, 1], uv[tj, 1, 1], uv[tj, 2, 1]) or \
                        max(uv[tj, 0, 1], uv[tj, 1, 1], uv[tj, 2, 1]) <= min(uv[ti, 0, 1], uv[ti, 1, 1], uv[ti, 2, 1]):
                    continue
                px = np.array([uv[ti, 0, 0], uv[ti, 1, 0], uv[ti, 2, 0]])
                py = np.array([uv[ti, 0, 1], uv[ti, 1, 1], uv[ti, 2, 1]])
                qx, qy, m = _clip(px, py, 3, uv[tj, 0, 0], uv[tj, 0, 1], uv[tj, 1, 0], uv[tj, 1, 1], uv[tj, 2, 0],
                                  uv[tj, 2, 1])
                area = 0.0
                for k in range(m):
                    area += qx[k] * qy[(k + 1) % m] - qx[(k + 1) % m] * qy[k]
                area *= 0.5
                ai = 0.5 * abs((px[1] - px[0]) * (py[2] - py[0]) - (px[2] - px[0]) * (py[1] - py[0]))
                if area > min_frac * ai:
                    pairs += 1
                    total += area
    return pairs, total


def coplanar_overlaps(corners, min_frac=1e-6):
    """(pairs, area) of triangles lying in one plane, facing the same way,
    that overlap (more than min_frac of the first's area)."""
    nt = len(corners)
    if nt < 2:
        return 0, 0.0
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    ok = norm > 0
    n = np.where(ok[:, None], cross / np.maximum(norm, 1e-300)[:, None], 0.0)
    scale = float(np.abs(corners).max()) or 1.0
    d = np.einsum("ij,ij->i", n, corners[:, 0])
    key = np.concatenate([np.round(n * 1e4), np.round(d / scale * 1e5)[:, None]], axis=1).astype(np.int64)
    order = np.lexsort(key.T[::-1])
    ks = key[order]
    new = np.ones(nt, bool)
    new[1:] = (ks[1:] != ks[:-1]).any(axis=1)
    starts = np.append(np.flatnonzero(new), nt).astype(np.int64)
    sizes = np.diff(starts)
    if not (sizes > 1).any():
        return 0, 0.0
    # project each triangle on its plane's dominant axis, counter-clockwise as seen from its front
    axis = np.argmax(np.abs(n), axis=1)
    u_ax, v_ax = (axis + 1) % 3, (axis + 2) % 3
    idx = np.arange(nt)
    uv = np.stack([corners[idx[:, None], [0, 1, 2], u_ax[:, None]], corners[idx[:, None], [0, 1, 2], v_ax[:, None]]],
                  axis=2)
    flip = n[idx, axis] < 0
    uv[flip] = uv[flip][:, [0, 2, 1]]
    return _overlaps(np.ascontiguousarray(uv), order.astype(np.int64), starts, float(min_frac))


NEARLY_CLOSED = 0.05  # a shell with at most this fraction of its triangles on an open edge (a scan's hole) is closed


def two_sided_shells(scene):
    """(closed shells, their triangles) among the two-sided triangles:
    edge-connected components whose edges two of their triangles share,
    but for a few (NEARLY_CLOSED: a scan's holes, a dropped sliver)."""
    ds = scene.double_sided[scene.material_ids]
    tri = np.nonzero(ds)[0]
    if len(tri) == 0:
        return 0, 0
    sub = scene.triangles[tri]
    start, adj = triangle_adjacency(scene.vertices, sub)
    _, weld = np.unique(np.asarray(scene.vertices, np.float64), axis=0, return_inverse=True)
    weld = weld.ravel()
    c = weld[sub]
    e = np.sort(np.concatenate([c[:, [0, 1]], c[:, [1, 2]], c[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(len(sub)), 3)
    _, inv, counts = np.unique(e, axis=0, return_inverse=True, return_counts=True)
    open_tri = np.zeros(len(sub), bool)
    open_tri[owner[counts[inv.ravel()] != 2]] = True
    label = _components(start, adj)
    shells, members = 0, 0
    for lab in np.unique(label):
        m = label == lab
        if m.sum() >= 4 and open_tri[m].mean() <= NEARLY_CLOSED:
            shells += 1
            members += int(m.sum())
    return shells, members


@njit(cache=True)
def _components(start, adj):
    n = start.shape[0] - 1
    label = np.full(n, -1, np.int64)
    stack = np.empty(n, np.int64)
    for s in range(n):
        if label[s] >= 0:
            continue
        label[s] = s
        top = 0
        stack[top] = s
        top += 1
        while top > 0:
            top -= 1
            t = stack[top]
            for k in range(start[t], start[t + 1]):
                u = adj[k]
                if label[u] < 0:
                    label[u] = s
                    stack[top] = u
                    top += 1
    return label


def geometry_report(scene) -> GeometryReport:
    corners = scene.triangle_corners()
    pairs, overlap = coplanar_overlaps(corners)
    shells, members = two_sided_shells(scene)
    emits = scene.emission.max(axis=1)[scene.material_ids] > 0
    both = int((emits & scene.double_sided[scene.material_ids]).sum())
    return GeometryReport(len(scene.triangles), _count_dropped(scene), int(pairs), float(overlap),
                          float(scene.triangle_areas().sum()), shells, members, both)
