"""Texel values: sample points on a layout's texels, the preview tier (the
voxel solution reconstructed at each texel) and the lightcuts tier
(adaptive shading, anti-aliasing, small triangles shaded at their
corners), inside-geometry texels and the fill around maps, and the atlas
of a layout.

A layout is per-triangle Charts (charts.py) or an XatlasLayout
(xatlas_charts.py); both answer the same protocol: per_triangle (do maps
follow triangles?), min_texel, chart_count, subtexel_charts(),
sample(corners, inset, bvh, lift) and pages(texels, emits)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..kernels.colour import LUMINANCE
from ..kernels.traverse import any_hit_batch
from .atlas import Lightmaps
from .charts import Charts, per_triangle_charts
from .texels import (INSET, between_lattice, contrast_texels, fill, inside_geometry, interpolate_corners,
                     open_edges, sub_texel_points)
from .smooth_cache import SmoothCache, cube_bins, representatives
from .voxel_irradiance import reconstruct
from .xatlas_charts import xatlas_layout

LIFT = 0.25   # cells (or texels, the smaller): texel points are lifted this far off their surface for rays
AA_CONTRAST = 0.1   # texels differing from a neighbour by more than this share of the larger are anti-aliased
NEAR_BACK = 2.0     # cells: a two-sided triangle seen from behind this near a texel's point counts as inside geometry
CORNER_IN = 0.25    # a sub-texel triangle's shading points: its corners moved this share of the way to its centroid
CLUSTER_CELL = 1.0  # texels: the grid of those clusters
CLUSTER_BINS = 16   # triangles under half a texel share a shading point when their normals share a cube-map cell
#                     of 1 / CLUSTER_BINS of a face's side (about 6 degrees: the cosine moves by at most ~0.1)
SAME_PLANE_COS = 0.999  # sparse bounced light: a lattice texel whose normal is this close lies on the same surface
STRIDE = 2          # adaptive shading: texels on this lattice are shaded first (a power of two)
SHIFT = 0.1         # texels: adaptive shading interpolates where the neighbours' points' mean lies this near the texel's


@dataclass(frozen=True)
class TexelStats:
    """What lightcuts texels cost: the cut sizes and shadow rays over the
    points shaded, texels shaded and interpolated (adaptive shading), small
    triangles' sides shaded at their corners, texels anti-aliased on a
    texel_samples x texel_samples grid, and the rays that gathered the
    bounced light (config.texel_gather)."""
    cut_mean: float
    cut_max: int
    shadow_rays: int
    points_shaded: int
    texels_shaded: int
    texels_interpolated: int
    subtexel_triangles: int
    texels_antialiased: int
    texel_samples: int
    gather_rays: int = 0


@dataclass(frozen=True)
class TexelSet:
    """The texels of every map, flat: map m (a per-triangle chart or an
    xatlas page) is the square map_size[m]^2 at map_offsets[m].
    layout: Charts or XatlasLayout; texel_tri (N,) int32 the triangle a
    texel samples (-1: none) and texel_back (N,) bool its back side;
    point (N, 3) float64 sample points; covered (N,) bool; inside (N,)
    bool covered texels hidden inside geometry; values (N, 3) float64 H
    after the fill; filled (N,) bool."""
    layout: object
    map_offsets: np.ndarray
    map_size: np.ndarray
    texel_tri: np.ndarray
    texel_back: np.ndarray
    point: np.ndarray
    covered: np.ndarray
    inside: np.ndarray
    values: np.ndarray
    filled: np.ndarray


def texel_size_for(solution, texel_density=None) -> float:
    """Scene units per texel: one voxel cell, or 1 / texel_density."""
    if texel_density:
        return 1.0 / float(texel_density)
    return float(solution.voxels.cell_size)


AUTO_XATLAS = 2.0   # --uv auto: xatlas charts once per-triangle maps would shade this many times their points


@dataclass(frozen=True)
class TexelPlan:
    """What a bake's lightmaps will be, decided before they are made:
    texel_size (scene units per texel), uv ('per-triangle' or 'xatlas'),
    texels (the layout's estimated texel count) and why: a sentence for
    the summary on how the size and the layout were chosen."""
    texel_size: float
    uv: str
    texels: int
    why: str


def scene_extent(scene) -> float:
    """The scene's thinnest extent that is not flat: the smallest side of
    its triangles' bounding box of at least 1/1000 of the largest (a room's
    height, a box's side; a lone floor's width, not its zero thickness)."""
    c = scene.triangle_corners().reshape(-1, 3)
    if not len(c):
        return 0.0
    ext = np.sort(c.max(axis=0).astype(np.float64) - c.min(axis=0))
    ext = ext[ext >= 1e-3 * ext[-1]]
    return float(ext[0]) if len(ext) and ext[-1] > 0 else 0.0


def plan_texels(scene, cell, texel_density=None, texels_across=0, uv="per-triangle",
                memory_budget_mb=float("inf")) -> TexelPlan:
    """The texel size and layout of a bake. texel_density (texels per
    scene unit) is taken as asked; otherwise the texel is the voxel `cell`
    or, when texels_across > 0, the scene's thinnest extent over
    texels_across where that is finer (detail follows the scene's scale,
    not the voxel budget), coarsened until the layout's texels fit the
    memory budget and this machine's memory (BYTES_PER_TEXEL each). uv
    'auto': per-triangle maps, unless they would hold more than AUTO_XATLAS
    times the texels of xatlas charts at that size (triangles under a
    texel or slivers, whose square maps are mostly margin); then xatlas."""
    if texel_density:
        size, how = 1.0 / float(texel_density), "as asked"
    else:
        size, how = float(cell), "one voxel cell"
        across = scene_extent(scene) / texels_across if texels_across else 0.0
        if 0 < across < size:
            size, how = across, f"the scene's thinnest extent over {texels_across}"
    why = []
    if uv == "auto":
        per, xa = shading_estimate(scene, size, "per-triangle"), shading_estimate(scene, size, "xatlas")
        uv = "xatlas" if per > AUTO_XATLAS * xa else "per-triangle"
        why.append(f"uv {uv} (auto: per-triangle maps would shade {per / max(xa, 1):.1f}x the points of charts)")
    n = texel_estimate(scene, size, uv)
    limit = min(float(memory_budget_mb), machine_memory_mb()) * 2 ** 20 / BYTES_PER_TEXEL
    if not texel_density:
        for _ in range(12):   # per-triangle maps' count is not quite quadratic in the size: a few steps
            if n <= limit:
                break
            size *= 1.02 * float(np.sqrt(n / limit))
            how = "coarsened to the memory budget"
            n = texel_estimate(scene, size, uv)
        if n > limit:   # per-triangle maps keep 8 x 8 texels however coarse: the triangles alone are too many
            from ..errors import BudgetError
            raise BudgetError(f"the lightmaps need about {n:,} texels ({n * BYTES_PER_TEXEL / 2 ** 20:,.0f} MiB to "
                              f"bake) even at {size:.3g} scene units a texel with --uv {uv}, over the memory budget of "
                              f"{limit * BYTES_PER_TEXEL / 2 ** 20:,.0f} MiB: raise --memory-budget or use --uv xatlas",
                              getattr(scene, "path", None))
    return TexelPlan(size, uv, int(n), "; ".join([how] + why))


def capped_note(layout, texel_size) -> str | None:
    """A per-triangle layout whose largest maps stopped at a page's size
    (charts.MAX_SIZE) holds coarser texels there than `texel_size` asks:
    the sentence that says how many and how coarse; None when every map
    keeps the size (and for xatlas, whose charts split across pages)."""
    from .charts import MAX_SIZE
    if not isinstance(layout, Charts) or not len(layout.texel):
        return None
    coarse = layout.texel > float(texel_size) * 1.001
    if not coarse.any():
        return None
    return (f"{int(coarse.sum()):,} of {len(layout.texel):,} triangle maps reached a page's size "
            f"({MAX_SIZE}x{MAX_SIZE}): their texels are up to {float(layout.texel.max()):.3g} scene units, coarser "
            f"than the {float(texel_size):.3g} asked for (--uv xatlas splits large surfaces and keeps the density)")


def charts_for(scene, texel_size) -> Charts:
    return per_triangle_charts(scene.triangle_corners(), scene.double_sided[scene.material_ids], texel_size)


def layout_for(scene, texel_size, uv="per-triangle"):
    """Charts (per-triangle) or XatlasLayout (xatlas)."""
    if uv == "xatlas":
        return xatlas_layout(scene.vertices, scene.triangles, scene.double_sided[scene.material_ids], texel_size)
    return charts_for(scene, texel_size)


# What a bake holds per texel at its peak (its point, normal, values, masks and indices while it shades, then the
# stored pages): the staircase's 41.4 M texels peaked at 7.3 GiB with its scene and voxel solution, the modern
# hall's 4.9 M at 1.2 GiB (about 160 bytes a texel over what the scene and solution hold)
BYTES_PER_TEXEL = 160
XATLAS_PADDING = 1.3   # an xatlas page's texels over the surface's: charts' borders and packing gaps


def texel_estimate(scene, texel_size, uv="per-triangle") -> int:
    """Texels a bake's layout will hold at this texel size, before any
    work: the per-triangle maps' own count (their sizes follow from the
    corners alone); for xatlas the surface's area (both faces of two-sided
    triangles) in texels, plus its padding."""
    if uv == "xatlas":
        c = scene.triangle_corners()
        area = 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)
        faces = 1 + np.asarray(scene.double_sided[scene.material_ids], np.int64)
        return int(np.ceil(XATLAS_PADDING * float((area * faces).sum()) / float(texel_size) ** 2))
    return charts_for(scene, texel_size).texel_count


def shading_estimate(scene, texel_size, uv="per-triangle") -> int:
    """Points a bake's layout shades at this texel size (what its texel
    time follows), before any work: for xatlas the surface's texels with
    their padding; per triangle, each map's texels on its triangle and a
    texel's band around its edges (the texels bilinear lookups read, which
    overlap the neighbours'), at most its square, and a sub-texel
    triangle's three corner points."""
    if uv == "xatlas":
        return texel_estimate(scene, texel_size, "xatlas")
    charts = charts_for(scene, texel_size)
    q = scene.triangle_corners().astype(np.float64)[charts.tri]
    area = 0.5 * np.linalg.norm(np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]), axis=1)
    rim = np.linalg.norm(q - np.roll(q, 1, axis=1), axis=2).sum(axis=1)
    t = float(texel_size)
    own = np.minimum(charts.size.astype(np.float64) ** 2, area / t ** 2 + rim / t + 1.0)
    return int(np.ceil(np.where(charts.subtexel, 3.0, own).sum()))


def machine_memory_mb() -> float:
    """This machine's physical memory in MiB (inf where it cannot be read)."""
    import os
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2 ** 20
    except (ValueError, OSError, AttributeError):
        return float("inf")


def check_texel_budget(scene, texel_size, uv, memory_budget_mb, what):
    """Raises BudgetError, naming `what` set the texel size, when the
    layout's texels would need more than the memory budget or this
    machine's memory."""
    from ..errors import BudgetError
    from .atlas import PAGE
    n = texel_estimate(scene, texel_size, uv)
    need = n * BYTES_PER_TEXEL / 2 ** 20
    machine = machine_memory_mb()
    limit = min(float(memory_budget_mb), machine)
    if need > limit:
        whose = "this machine's memory" if machine < memory_budget_mb else "the memory budget (--memory-budget)"
        raise BudgetError(f"{what} ({texel_size:.3g} scene units a texel) asks for about {n:,} texels "
                          f"({-(-n // PAGE ** 2):,} pages of {PAGE}x{PAGE}), about {need:,.0f} MiB to bake, over "
                          f"{whose} of {limit:,.0f} MiB: lower --texel-density", scene.path)
    return n


def sample_points(layout, corners, inset=0.0, bvh=None, lift=0.0, open_edge=None):
    """(map_offsets, map_size, point, covered, texel_tri, texel_back, owner,
    corners2d): points keep `inset` texels in from the open edges
    (texels.inset, texels.open_edges; open_edge (nt, 3) bool, None: found
    here); texel k's triangle side has its corners at
    corners2d[owner[k]] (3, 2) in its map's texel units. With the scene's
    bvh, a per-triangle texel whose centre lies on the surface beyond its
    triangle's edge samples the centre (texels.onto_coplanar: no seams
    along the edges between coplanar triangles)."""
    return layout.sample(corners, inset, bvh, lift, open_edge)


def preview_texels(prepared, solution, layout, seed=0) -> TexelSet:
    """The preview tier: texel values from the voxel solution."""
    bvh, surfaces = prepared.bvh, prepared.surfaces
    vox = solution.voxels
    h = float(vox.cell_size)
    corners = surfaces.arrays.corners
    texel = layout.min_texel
    lift = LIFT * min(h, texel)
    off, size, point, covered, ttri, tback, owner, _ = sample_points(layout, corners, 0.0, bvh, lift)
    small, cpts, _ = corner_points(layout, corners)
    by_corners = layout.subtexel[owner] if len(small) else np.zeros(len(point), bool)
    inside = inside_geometry(bvh.arrays, surfaces.arrays.double_sided, surfaces.arrays.tri_material, corners, ttri,
                             tback, point, covered & ~by_corners, lift, np.inf, NEAR_BACK * h, seed)

    def at(tri, back, pts, ok):
        return reconstruct(bvh.arrays, corners, tri, back, pts, ok, np.ascontiguousarray(solution.irradiance),
                           vox.arrays(), vox.lookup(), lift)

    values, found = at(ttri, tback, point, covered & ~by_corners)
    if len(small):  # sub-texel triangles: the solution at their corner points, interpolated (as lightcuts_texels)
        cv, cf = at(np.repeat(layout.tri[small], 3).astype(np.int32), np.repeat(layout.back[small], 3),
                    np.ascontiguousarray(cpts.reshape(-1, 3)), np.ones(3 * len(small), bool))
        cv, cf = cv.reshape(-1, 3, 3), cf.reshape(-1, 3)
        n = cf.sum(axis=1)
        mean = (cv * cf[..., None]).sum(axis=1) / np.maximum(n, 1)[:, None]
        cv = np.where(cf[..., None], cv, mean[:, None, :])   # a corner that found no voxel: the others' mean
        corner_values(layout, corners, small, cv, point, off, values)
        size_s = layout.size[small].astype(np.int64) ** 2
        found[np.repeat(off[small] - np.cumsum(size_s) + size_s, size_s) + np.arange(int(size_s.sum()))] = \
            np.repeat(n > 0, size_s)
    return finish(layout, off, size, ttri, tback, point, covered, inside, values, found)


def side_normals(corners, texel_tri, texel_back):
    """(N, 3) unit normal of each texel's triangle side (0 where none)."""
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    out = np.empty((len(texel_tri), 3))
    # a kernel, not numpy's fancy indexing, which runs on one thread over every texel of a per-triangle layout
    _texel_normals(n, np.asarray(texel_tri), np.asarray(texel_back, np.bool_), out)
    return out


@njit(cache=True, parallel=True)
def texel_coords(off, size, total):
    """(column, row) (N,) int32 of every texel in its map (map m: the
    size[m]^2 texels from off[m], row-major): one pass, where numpy's
    mod and floor division over every texel of a per-triangle layout
    took a second."""
    qi = np.zeros(total, np.int32)
    qj = np.zeros(total, np.int32)
    for m in prange(len(size)):
        s = size[m]
        for k in range(s * s):
            qi[off[m] + k] = k % s
            qj[off[m] + k] = k // s
    return qi, qj


@njit(cache=True, parallel=True)
def _texel_normals(n, texel_tri, texel_back, out):
    for k in prange(len(texel_tri)):
        t = texel_tri[k]
        if t < 0:   # most of a per-triangle layout's texels are its maps' empty margins
            out[k, 0] = out[k, 1] = out[k, 2] = 0.0
        else:
            s = -1.0 if texel_back[k] else 1.0
            out[k, 0], out[k, 1], out[k, 2] = s * n[t, 0], s * n[t, 1], s * n[t, 2]


def lightcuts_texels(prepared, solution, layout, lights, config, progress=None,
                     texel_size=None, executor=None) -> tuple[TexelSet, TexelStats]:
    """The default and high tiers: each texel's irradiance by lightcuts over
    the VPLs (direct light from the emitters' VPLs with shadow rays, the
    indirect from the voxels'), at its sample point, on its side.
    Sub-texel triangles are shaded at their three corner points and
    interpolated over their maps; those under half a texel are shaded once,
    each cluster of them in one texel-sized cell, of one material, facing
    one way within about 6 degrees, at one of its centroids
    (corner_points, small_triangle_light). Adaptive shading
    (`interpolate` > 0): the texels on the even lattice (every STRIDE-th
    row and column of a map) are shaded first; a texel between lattice
    texels (two beside it in its row or column, or four diagonal ones)
    that agree within `interpolate` of the largest takes their mean
    (texels.between_lattice), the others are shaded (a shadow's edge, a
    contact, a triangle's edge). Where the light is smooth this shades a
    quarter of the texels, and the mean also averages out the cuts' own
    error. Then anti-aliasing:
    texels that differ from a neighbour by more than `contrast` (a shadow's
    edge, a contact) take the mean of a samples x samples grid of points
    over their square instead (samples 1: off; texels.sub_texel_points;
    grid points beyond the triangle on a coplanar one that continues the
    surface are taken there, not clamped onto the shared edge).
    With texel_indirect_stride > 1 all this is the sharp part of the light
    (the emitters' VPLs, punctual lights), and the smooth part (the
    voxels' VPLs, the sky: split_lights) is shaded on a sparse lattice
    (sparse_bounced), a sub-texel triangle's at its centroid; the sharp
    part's edges alone call for anti-aliasing. With config.texel_gather
    the bounced light is gathered (gather.py; with
    config.texel_gather_spacing at records over the surfaces instead of
    the lattice, smooth_cache.py, the sky's light staying on the lattice),
    whose error needs no floor:
    the smooth part is then shaded first, and the sharp part's cuts are
    bounded against the texel's whole light (their floor: the smooth
    light there), as the smooth part's cuts are otherwise.

    texel_size: the texel the layout was made for (TexelPlan; None: one
    voxel cell or config.texel_density). executor: where the points are
    shaded, tile by tile (bake/executor.py; None: in this process); the
    result is the same bytes on any.
    config: the BakeConfig (its lightcuts' epsilon and cap, the solver's
    seed, texel_samples as `samples`, texel_contrast as `contrast`,
    texel_interpolate as `interpolate`)."""
    from ..bake.executor import LocalExecutor, ShadeContext
    from ..lights import split_lights
    bvh, surfaces = prepared.bvh, prepared.surfaces
    epsilon, cap, seed = config.lightcuts.epsilon, config.lightcuts.cap, config.solver.seed
    stride = config.texel_indirect_stride
    bounced = None
    gather = 0
    if stride > 1:   # sharp light at every point, the smooth light on a sparse lattice (shade_bounced below)
        lights, bounced = split_lights(lights, seed, tree=config.texel_gather == 0)
        gather = config.texel_gather if bounced is not None else 0
    spacing = config.texel_gather_spacing if gather else 0.0   # cells; 0: the gather on each map's lattice
    sky = bounced is not None and len(bounced.sky) > 0
    samples, contrast, interpolate = config.texel_samples, config.texel_contrast, config.texel_interpolate
    h = float(solution.voxels.cell_size)
    corners = surfaces.arrays.corners
    texel = layout.min_texel
    lift = LIFT * min(h, texel)
    edges = open_edges(corners)
    off, size, point, covered, ttri, tback, owner, q_all = sample_points(layout, corners, INSET, bvh, lift, edges)
    small, cpts, once = corner_points(layout, corners)
    by_corners = layout.subtexel[owner] if len(small) else np.zeros(len(point), bool)
    # the inside test is per texel point; a sub-texel triangle's texels have no points of their own
    inside = inside_geometry(bvh.arrays, surfaces.arrays.double_sided, surfaces.arrays.tri_material, corners, ttri,
                             tback, point, covered & ~by_corners, lift, np.inf, NEAR_BACK * h, seed)
    normals = side_normals(corners, ttri, tback)
    found = covered & (ttri >= 0)
    values = np.zeros((len(point), 3))
    cuts, rays, gathered, uncut = [], [0], [0], [0]

    run = executor or LocalExecutor()
    run.open(ShadeContext(bvh, surfaces, lights, bounced, solution if gather else None, lift, epsilon, gather))

    def shade(pts, nrm, ok, light=lights, floor=None, c_max=cap, exact=True, count=True):
        out, c, r = run.shade("sharp" if light is lights else "smooth", pts, nrm, ok, floor, c_max, exact,
                              progress if count else None)
        cuts.append(c[ok])
        rays[0] += r
        return out

    def gathered_at(pts, nrm):
        gathered[0] += len(pts) * gather
        return run.shade("gather", pts, nrm)[0]

    def shade_bounced(pts, nrm, floor):
        """The smooth light at points whose sharp light has luminance
        `floor`: its cut's error is bounded against the whole."""
        if gather and not sky:   # no sky, and the voxels' light by the gather: no cut at all
            out = np.zeros((len(pts), 3))
            uncut[0] += len(pts)
        else:
            out = shade(pts, nrm, np.ones(len(pts), bool), bounced, floor, config.texel_indirect_cap, False, False)
        if gather and not spacing:   # `bounced` holds the sky alone: the voxels' light by the gather
            out += gathered_at(pts, nrm)
        return out

    want = found & ~by_corners
    cache = None
    # the texel asked for (a small triangle's map has finer texels of its own)
    cluster_cell = CLUSTER_CELL * (texel_size or texel_size_for(solution, config.texel_density))
    small_normals = side_normals(corners, layout.tri[small], layout.back[small]) if len(small) else None
    small_material = surfaces.arrays.tri_material[layout.tri[small]] if len(small) else None
    if spacing:   # the gathered light at records spread over the surfaces, interpolated (smooth_cache.py)
        at = np.nonzero(want & ~inside)[0]
        sp, sn = smooth_points(cpts, small_normals, once, small_material, cluster_cell) if len(small) else \
            (np.zeros((0, 3)), np.zeros((0, 3)))
        cache = SmoothCache(bvh.arrays, gathered_at, np.concatenate([point[at], sp]),
                            np.concatenate([normals[at], sn]), spacing * h, lift)
        cached = np.zeros((len(point), 3))
        cached[at] = cache.values[:len(at)]
    if len(small):
        smooth_small = shade_bounced if bounced is not None else None
        if cache is not None:
            def smooth_small(p, n, f):
                return cache.values[len(at):] + (shade_bounced(p, n, f) if sky else 0.0)
        cv = small_triangle_light(lambda p, n, f: shade(p, n, np.ones(len(p), bool), floor=f),
                                  smooth_small, cpts, small_normals, once, small_material, cluster_cell, bool(gather))
        corner_values(layout, corners, small, cv, point, off, values)
    bounced_args = None
    known = None
    sfloor = None   # the smooth light's luminance at each texel: what the sharp cuts' error is bounded against too
    if bounced is not None:
        reach = np.inf if layout.per_triangle else 1.5 * stride * texel   # xatlas: another chart
        bounced_args = (bvh.arrays, point, normals, want & ~inside, (ttri >= 0) & ~inside, off, size, stride, lift,
                        reach)
        if gather:   # the gathered smooth light first (it takes no floor), its agreement test once the sharp is known
            known = (np.full(len(point), -1, np.int32), [])
            if cache is None or sky:
                first = sparse_bounced(shade_bounced, bounced_args[0], np.zeros((len(point), 3)),
                                       *bounced_args[1:], known=known)
                if cache is not None:
                    first += cached
            else:
                first = cached
            sfloor = (first @ LUMINANCE).astype(np.float32)   # a floor: float32 is plenty
            del first

    def floor_at(idx):
        return None if sfloor is None else sfloor[idx]
    todo = np.nonzero(want)[0]
    between = np.zeros(len(point), bool)
    if interpolate > 0:   # shade the even lattice, then each texel between agreeing lattice texels takes their mean
        qi, qj = texel_coords(off, size, len(point))
        on = want & (((qi | qj) & (STRIDE - 1)) == 0)   # steps are powers of two
        first = np.nonzero(on)[0]
        values[first] = shade(point[first], normals[first], np.ones(len(first), bool), floor=floor_at(first))
        step = STRIDE // 2
        shift = SHIFT * (np.broadcast_to(layout.texel, len(size)) if layout.per_triangle else np.full(len(size), texel))
        while step >= 1:
            level = want & (((qi | qj) & (step - 1)) == 0) & ~on
            reach = np.inf if layout.per_triangle else 2.5 * step * texel  # xatlas: another chart
            got = between_lattice(values, values @ LUMINANCE, on & ~inside, level & ~inside, point, normals, off, size,
                                  reach, float(interpolate), step, np.ascontiguousarray(shift, np.float64))
            rest = np.nonzero(level & ~got)[0]
            values[rest] = shade(point[rest], normals[rest], np.ones(len(rest), bool), floor=floor_at(rest))
            between |= got
            on |= level
            step //= 2
    else:
        values[todo] = shade(point[todo], normals[todo], np.ones(len(todo), bool), floor=floor_at(todo))
    indirect = np.zeros((len(point), 3))
    if bounced is not None and (cache is None or sky):
        indirect = sparse_bounced(shade_bounced, bounced_args[0], values, *bounced_args[1:], float(contrast),
                                  known=known)
    if cache is not None:   # the records' spread against the texel's whole light: contacts gathered at the texel
        lum = np.zeros(len(cache.points))
        lum[:len(at)] = (values[at] + indirect[at]) @ LUMINANCE
        lum[len(at):] = np.inf   # small triangles' points: their light is already taken
        cache.refine(lum, float(contrast))
        indirect[at] += cache.values[:len(at)]
    aa = np.zeros(0, np.int64)
    if samples > 1:
        # the sharp part's edges (the smooth part is the texel's own: slow by construction, shaded apart)
        valid = found & ~inside & ~by_corners    # interpolated texels: no point of their own to refine
        reach = np.inf if layout.per_triangle else 2.5 * texel  # an xatlas page's neighbour may be another chart
        lum = values @ LUMINANCE
        aa = np.nonzero(contrast_texels(lum, lum + indirect @ LUMINANCE, valid, point, off, size, reach,
                                        float(contrast)))[0]
        if len(aa):
            m = np.searchsorted(off, aa, side="right") - 1
            per = layout.per_triangle
            pts, ok = sub_texel_points(bvh.arrays, corners, aa, owner, q_all, off[m], size[m], ttri, tback, point,
                                       int(samples), float(INSET), edges, lift,
                                       layout.axis if per else np.zeros(1, np.int8),
                                       layout.origin if per else np.zeros((1, 2)),
                                       layout.texel if per else np.zeros(1), per)
            n_sub = samples * samples
            sub = shade(pts, np.repeat(normals[aa], n_sub, axis=0), ok,
                        floor=None if sfloor is None else np.repeat(indirect[aa] @ LUMINANCE, n_sub))
            n_ok = ok.reshape(-1, n_sub).sum(axis=1)
            mean = sub.reshape(-1, n_sub, 3).sum(axis=1) / np.maximum(n_ok, 1)[:, None]
            keep = n_ok > 0  # every sub-point hidden from the texel's own: its own value stays
            values[aa[keep]] = mean[keep]
    values += indirect   # the sub-points' sharp light, the texel's smooth light
    ts = finish(layout, off, size, ttri, tback, point, covered, inside, values, found)
    cuts = np.concatenate(cuts) if cuts else np.zeros(0, np.int64)
    stats = TexelStats(float(cuts.mean()) if len(cuts) else 0.0, int(cuts.max(initial=0)), rays[0],
                       int(len(cuts)) + uncut[0],
                       int(len(todo) - between.sum()), int(between.sum()), int(len(small)), int(len(aa)),
                       int(samples), gathered[0])
    return ts, stats


def sparse_bounced(shade_bounced, bvh, direct, point, normals, want, usable, off, size, stride, lift, reach=np.inf,
                   agree=0.0, known=None):
    """(N, 3) the smooth light (bounced, and the sky's: split_lights) of
    the `want` texels, shaded on a sparse lattice of each map and bilinear
    between. A map's lattice columns are every stride-th one and its last
    (rows alike); a texel between them takes the bilinear mean of the
    lattice texels around it (those of positive weight), shaded for it
    wherever they are `usable` (a point on the texel's triangle, not inside
    geometry: beyond a triangle's edge too), when all of them are, lie on
    its plane within `reach` (an xatlas page's neighbouring texel may be
    another chart), are in sight of it `lift` off the surface (nothing
    standing between, as a wall on a floor triangle that runs under it)
    and, with agree > 0, agree: their luminances spread by at most `agree`
    of the largest plus the texel's direct light (a contact's occlusion
    falls off faster than a bilinear lattice follows); every other texel
    is shaded itself. direct (N, 3): each texel's direct light, the floor
    of the cuts' error bound (a lattice texel takes the largest of the
    texels it serves). known: (slot (N,) int32, rows: a list of (n, 3)
    arrays), where an earlier call put the smooth light it shaded (texel
    i's is row slot[i] of the rows stacked; -1: not shaded), not shaded
    again (what this call shades is added): a second pass over the same
    texels with
    their direct light known shades only what its agreement test adds
    (for a smooth part whose error bound takes no floor: the gather)."""
    out = np.zeros((len(point), 3))

    def shaded(idx, floors):
        if known is None:
            return shade_bounced(point[idx], normals[idx], floors)
        slot, rows = known   # rows for the shaded texels only: a layout's texels are mostly margins
        new = slot[idx] < 0
        if new.any():
            j = idx[new]
            base = sum(len(r) for r in rows)
            rows.append(shade_bounced(point[j], normals[j], floors[new]))
            slot[j] = base + np.arange(len(j))
        return np.concatenate(rows)[slot[idx]]

    k = np.nonzero(want)[0]
    if not len(k):
        return out
    m = np.searchsorted(off, k, side="right") - 1
    s, q = size[m].astype(np.int64), k - off[m]
    qi, qj = q % s, q // s
    i0, j0 = qi - qi % stride, qj - qj % stride
    i1, j1 = np.minimum(i0 + stride, s - 1), np.minimum(j0 + stride, s - 1)
    fi = np.where(i1 > i0, (qi - i0) / np.maximum(i1 - i0, 1), 0.0)
    fj = np.where(j1 > j0, (qj - j0) / np.maximum(j1 - j0, 1), 0.0)
    lum = direct[k] @ LUMINANCE
    corners = []
    ok = np.ones(len(k), bool)
    for ci, cj, w in ((i0, j0, (1 - fi) * (1 - fj)), (i1, j0, fi * (1 - fj)), (i0, j1, (1 - fi) * fj),
                      (i1, j1, fi * fj)):
        need = w > 0
        idx = off[m] + cj * s + ci
        same = usable[idx] & (np.einsum("ij,ij->i", normals[idx], normals[k]) >= SAME_PLANE_COS)
        if np.isfinite(reach):
            same &= np.linalg.norm(point[idx] - point[k], axis=1) <= reach
        ok &= same | ~need
        corners.append((idx, np.where(need, w, 0.0)))
    # the texels between lattice texels in sight of them all (the lattice texels themselves: weight 1 on their own)
    own = np.ones(len(k), bool)
    for idx, w in corners:
        own &= (w == 0) | (idx == k)
    for idx, w in corners:
        sel = np.nonzero(ok & ~own & (w > 0))[0]
        a = point[k[sel]] + lift * normals[k[sel]]
        d = point[idx[sel]] + lift * normals[idx[sel]] - a
        dist = np.linalg.norm(d, axis=1)
        ok[sel[any_hit_batch(bvh, a, d / np.maximum(dist, 1e-300)[:, None], 0.0, dist)]] = False
    need_at = np.zeros(len(point), bool)
    floor = np.zeros(len(point))
    for idx, w in corners:
        sel = ok & (w > 0)
        need_at[idx[sel]] = True
        np.maximum.at(floor, idx[sel], lum[sel])
    need_at[k[~ok]] = True   # the texels shaded themselves
    floor[k[~ok]] = lum[~ok]
    at = np.nonzero(need_at)[0]
    got = np.zeros((len(point), 3))
    got[at] = shaded(at, floor[at])
    if agree > 0:
        between = ok & ~own
        g = got @ LUMINANCE
        hi, lo = np.zeros(len(k)), np.full(len(k), np.inf)
        for idx, w in corners:
            hi = np.where(w > 0, np.maximum(hi, g[idx]), hi)
            lo = np.where(w > 0, np.minimum(lo, g[idx]), lo)
        bad = np.nonzero(between & (hi - lo > agree * (hi + lum)))[0]
        if len(bad):
            got[k[bad]] = shaded(k[bad], lum[bad])
            ok[bad] = False
    acc = np.zeros((len(k), 3))
    for idx, w in corners:
        acc += np.where(ok, w, 0.0)[:, None] * got[idx]
    out[k] = np.where(ok[:, None], acc, got[k])
    return out


def corner_points(layout, corners):
    """The charts of sub-texel triangles (Charts.subtexel; none for xatlas
    layouts, whose texels follow the surface's area, not its triangles),
    their shading points (m, 3, 3) and whether each is shaded once (m,)
    bool: each corner moved CORNER_IN of the way towards the centroid (off
    the edge where a neighbouring surface may meet it: the same reason as
    texels.INSET); a triangle no wider than Charts.centroid's span has all
    three at its centroid, and is shaded once."""
    charts = layout.subtexel_charts()
    if not len(charts):
        return np.zeros(0, np.int64), np.zeros((0, 3, 3)), np.zeros(0, bool)
    c = corners[layout.tri[charts]]
    mid = c.mean(axis=1, keepdims=True)
    once = layout.centroid[charts]
    pts = np.where(once[:, None, None], mid, c + CORNER_IN * (mid - c))
    return charts, pts, once


def point_clusters(points, normals, material, cell):
    """Small triangles shaded together: (rep (k,), of (m,), normal (k, 3)).
    Points (m, 3) (centroids) in one cube of a grid `cell` apart, of one
    material, whose unit normals (m, 3) fall in one of CLUSTER_BINS^2
    cells of the same face of a cube map (about 90 / CLUSTER_BINS degrees
    wide) form a cluster; it is shaded at rep, its member nearest the
    members' mean (a point on a surface: the mean of a curved patch's
    points lies under it), ties to the first, with the members' mean
    normal; of: each point's cluster, in the order of the clusters' keys."""
    if not len(points):
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3))
    key = np.column_stack([np.floor(points / cell).astype(np.int64), cube_bins(normals, CLUSTER_BINS),
                           np.asarray(material, np.int64)])
    return representatives(points, normals, key)


def smooth_points(pts, normals, once, material, cell):
    """(points (k, 3), normals (k, 3)): where small_triangle_light shades
    the smooth light of sub-texel triangles (shading points pts (m, 3, 3),
    side normals (m, 3)): the centroids of those shaded at three corners,
    then each cluster's point of those shaded once."""
    three = np.nonzero(~once)[0]
    one = np.nonzero(once)[0]
    rep, _, cnormal = point_clusters(pts[one, 0], normals[one], material[one], cell)
    return np.concatenate([pts[three].mean(axis=1), pts[one[rep], 0]]), np.concatenate([normals[three], cnormal])


def small_triangle_light(shade, shade_smooth, pts, normals, once, material, cell, smooth_first=False):
    """(m, 3, 3) the light at sub-texel triangles' shading points (m, 3, 3)
    with their sides' unit normals (m, 3): at each corner, or for those
    shaded once (corner_points) at their cluster's point (point_clusters,
    grid `cell` apart: a texel): shade(points, normals) -> (n, 3) the
    sharp light; shade_smooth(points, normals, floors) -> (n, 3) the smooth
    light (None: none apart), once per triangle at its centroid or its
    cluster's point, its cut bounded against the brightest sharp light of
    the points it serves. smooth_first: the smooth light is shaded first
    (its own error takes no floor: the gather) and bounds the sharp
    light's cuts instead, shade(points, normals, floors). Returns
    (light, points shaded once)."""
    three = np.nonzero(~once)[0]
    one = np.nonzero(once)[0]
    rep, of, cnormal = point_clusters(pts[one, 0], normals[one], material[one], cell)
    sharp_at = (np.concatenate([pts[three].reshape(-1, 3), pts[one[rep], 0]]),
                np.concatenate([np.repeat(normals[three], 3, axis=0), cnormal]))
    smooth_at = smooth_points(pts, normals, once, material, cell)
    smooth = None
    if shade_smooth is not None and smooth_first:
        smooth = shade_smooth(*smooth_at, np.zeros(len(smooth_at[0])))
        lum = smooth @ LUMINANCE
        got = shade(*sharp_at, np.concatenate([np.repeat(lum[:len(three)], 3), lum[len(three):]]))
    else:
        got = shade(*sharp_at, None)
    out = np.empty((len(pts), 3, 3))
    out[three] = got[:3 * len(three)].reshape(-1, 3, 3)
    out[one] = got[3 * len(three):][of][:, None, :]
    if smooth is not None:
        out[three] += smooth[:len(three), None, :]
        out[one] += smooth[len(three):][of][:, None, :]
    elif shade_smooth is not None:
        lum = out @ LUMINANCE
        floor = np.zeros(len(rep))
        np.maximum.at(floor, of, lum[one, 0])
        smooth = shade_smooth(*smooth_at, np.concatenate([lum[three].max(axis=1), floor]))
        out[three] += smooth[:len(three), None, :]
        out[one] += smooth[len(three):][of][:, None, :]
    return out


def corner_values(layout, corners, charts, values_at_corners, point, off, values):
    """Fills, in place, the texels of the sub-texel charts `charts` from the
    values at their corner points (m, 3, 3): linear in the texel's point
    over the triangle (barycentrics taken against the corner points,
    extrapolated a little towards the true corners), never below 0."""
    interpolate_corners(corners, layout.tri[charts], off[charts], layout.size[charts].astype(np.int64),
                        np.ascontiguousarray(values_at_corners, np.float64), point, float(CORNER_IN), values)


def finish(layout, off, size, ttri, tback, point, covered, inside, values, found) -> TexelSet:
    """Texels inside geometry next to a valid one take their valid
    neighbours' mean (one ring: what bilinear filtering at the object's
    outline reads), the other covered ones keep their own value, and the
    texels around the triangles are filled from them (texels.py)."""
    valid = covered & found & ~inside
    values[~(covered & found)] = 0.0   # in place: a per-triangle layout's values are millions of texels
    filled = valid.copy()
    fill(values, filled, off, size, 1, covered & found & inside)
    filled |= covered & found  # deeper inside texels: their own value
    fill(values, filled, off, size)
    return TexelSet(layout, off, size, ttri, tback, point, covered, inside, values, filled)


def atlas_for(scene, texels: TexelSet) -> Lightmaps:
    emits = scene.emission.max(axis=1)[scene.material_ids] > 0
    return texels.layout.pages(texels, emits)
