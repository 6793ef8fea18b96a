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

from .overlaps import OVERLAP_FRAC, overlap_pairs, plane_groups
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
    overlaps_cut: int = 0         # coplanar triangles the loader cut where another covered them

    def summary(self) -> str:
        lines = [f"geometry: {self.triangles} triangles, area {self.area:.4g}"]
        if self.duplicates_dropped:
            lines.append(f"  {self.duplicates_dropped} duplicate triangles dropped when loading (counted once)")
        if self.overlaps_cut:
            lines.append(f"  {self.overlaps_cut} coplanar triangles overlapping another facing the same way: the "
                         f"overlap was cut out of them when loading (counted once)")
        if self.overlapping_pairs:
            lines.append(f"  {self.overlapping_pairs} pairs of coplanar triangles overlap facing the same way: "
                         f"{self.overlap_area:.4g} ({100 * self.overlap_area / max(self.area, 1e-300):.2f}% of the "
                         f"area) counts twice in the voxels: a one-sided triangle over a two-sided one (make them both one-sided, or "
                         f"remove the duplicated part of the mesh)")
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


def _count_in_notes(scene, marker, after) -> int:
    """The number right after `after` in the loader's note holding `marker`."""
    for note in scene.warnings:
        if marker in note and after in note:
            words = note.split(after, 1)[1].split()
            if words and words[0].isdigit():
                return int(words[0])
    return 0


def coplanar_overlaps(corners, min_frac=OVERLAP_FRAC):
    """(pairs, area) of triangles lying in one plane, facing the same way,
    that overlap (more than min_frac of the smaller's area). The loader
    cuts these (overlaps.cut_overlaps); what is left is a one-sided
    triangle over a two-sided one."""
    if len(corners) < 2:
        return 0, 0.0
    uv, order, starts, _, _ = plane_groups(corners)
    if len(order) == 0:
        return 0, 0.0
    _, _, area = overlap_pairs(uv, order, starts, float(min_frac))
    return len(area), float(area.sum())


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
    return GeometryReport(len(scene.triangles), _count_in_notes(scene, "duplicate triangle", "dropped"), int(pairs),
                          float(overlap), float(scene.triangle_areas().sum()), shells, members, both,
                          _count_in_notes(scene, "coplanar triangle", "overlapping part out of"))


def describe(scene) -> str:
    """What `voxbake info` prints: triangles, bounds, materials, emitters
    with their power, punctual lights, the sky and the cameras."""
    def a(x, p=4):
        return np.array2string(np.asarray(x), precision=p)
    lo, hi = scene.bounds()
    power = scene.emitted_power()
    out = [f"scene      {scene.path}",
           f"triangles  {len(scene.triangles)}  (vertices {len(scene.vertices)}, surface area "
           f"{scene.triangle_areas().sum():.6g})",
           f"bounds     min {a(lo)}  max {a(hi)}  size {a(hi - lo)}",
           f"materials  {len(scene.materials)}"]
    for i, m in enumerate(scene.materials):
        n = int((scene.material_ids == i).sum())
        em = f"  emits L_e {a(m.emission)}" if m.emission.max() > 0 else ""
        tex = "  textured" if m.texture is not None else ""
        tex += f"  alpha mask (cutoff {m.alpha_cutoff:g})" if m.masked else ""
        tex += f"  thin glass (transmission {m.transmission:g})" if m.transmission > 0 else ""
        out.append(f"  [{i}] {m.name:<20} albedo {a(m.albedo, 3)}  {'double' if m.double_sided else 'one'}-sided  "
                   f"{n} triangles{em}{tex}")
    out.append(f"emitters   {len(scene.emitter_triangles())} triangles, total emitted power {a(power, 5)} W"
               f" (sum {power.sum():.6g} W)")
    out.append(f"lights     {len(scene.lights)} punctual")
    for light in scene.lights:
        unit = "W/m^2" if light.kind == "directional" else "W/sr"
        out.append(f"  {light.name:<20} {light.kind:<12} {a(light.intensity)} {unit}")
    if scene.sky is not None:
        where = "upper hemisphere" if scene.sky.hemisphere else "whole sphere"
        out.append(f"sky        radiance {a(scene.sky.radiance)} W m^-2 sr^-1 ({where})")
    out.append(f"cameras    {len(scene.cameras)}")
    for i, c in enumerate(scene.cameras):
        out.append(f"  [{i}] {c.name:<20} at {a(c.position)} looking {a(c.forward, 3)}  yfov "
                   f"{np.degrees(c.yfov):.1f} deg")
    return "\n".join(out)
