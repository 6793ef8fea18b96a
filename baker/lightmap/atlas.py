"""Lightmap atlases: single-colour maps shrunk, identical maps stored once,
the rest packed into 512 x 512 pages by a quadtree (docs/design.md
section 8).

- Stored precision: texel values are rounded to half floats (what the
  bake file's full-precision pages hold) before anything is compared, so
  "identical" means identical in the file.
- Single colour: a map whose filled texels all lie within CONSTANT_REL of
  their mean (per channel, relative to the brightest channel's mean)
  becomes an 8 x 8 map of the mean, its triangle's UVs all at the centre.
- Deduplication: a 64-bit hash (BLAKE2b) of size and contents, then an
  exact compare of the bytes: equal maps are stored once and shared.
- Quadtree: maps are power-of-two squares of 8 .. 512 texels. Sorted by
  size, largest first, each takes the first free node of its level of a
  quadtree over the page. With that order the first free node is always
  the next one in Z (Morton) order: a cursor counting 8 x 8 blocks in
  Z order places each map at the cursor and advances it by the map's
  blocks, so a page fills with no gap, and a new page opens when the next
  map would pass the page's end.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .charts import MIN_SIZE

PAGE = 512
CONSTANT_REL = 1e-3    # spread within this fraction of the mean: a single-colour map
BLOCKS = (PAGE // MIN_SIZE) ** 2


@dataclass(frozen=True)
class Lightmaps:
    """pages (P, PAGE, PAGE, 3) float32 irradiance H (half-float values);
    chart_page (nc,) int32; chart_uv (nc, 3, 2) float32 each chart's
    triangle corners in its page (u right, v down, 0..1); page_scale (P,)
    float32 the brightest non-emitter texel of each page (the 8-bit PNG's
    intensity); counts: maps, unique, constant, texels (of the charts,
    before dedup), texels_stored, pages."""
    pages: np.ndarray
    chart_page: np.ndarray
    chart_uv: np.ndarray
    page_scale: np.ndarray
    counts: dict

    @property
    def dedup_ratio(self) -> float:
        """Maps over distinct maps stored (1: nothing shared)."""
        return self.counts["maps"] / max(1, self.counts["unique"])


def morton_xy(index):
    """(x, y) of the index-th cell of a Z-order curve (x from even bits)."""
    index = np.asarray(index, np.int64)
    x = np.zeros_like(index)
    y = np.zeros_like(index)
    for b in range(16):
        x |= ((index >> (2 * b)) & 1) << b
        y |= ((index >> (2 * b + 1)) & 1) << b
    return x, y


def pack_quadtree(sizes):
    """Places squares of power-of-two `sizes` (each MIN_SIZE .. PAGE) on
    PAGE x PAGE pages. Returns page (n,), x (n,), y (n,) int64 (texels,
    top-left corner), in the input's order, and the page count."""
    sizes = np.asarray(sizes, np.int64)
    n = len(sizes)
    order = np.argsort(-sizes, kind="stable")
    page = np.empty(n, np.int64)
    pos = np.empty(n, np.int64)
    p, cursor = 0, 0
    for i in order:
        blocks = (sizes[i] // MIN_SIZE) ** 2
        if cursor + blocks > BLOCKS:
            p, cursor = p + 1, 0
        page[i], pos[i] = p, cursor
        cursor += blocks
    bx, by = morton_xy(pos)
    return page, bx * MIN_SIZE, by * MIN_SIZE, (p + 1 if n else 0)


def to_stored(values):
    """Texel values as the file stores them (half floats, >= 0)."""
    return np.maximum(values, 0.0).astype(np.float16)


@njit(cache=True, inline="always")
def half_value(bits):
    """The value of a half float given as its bits (uint16), exactly
    (numba has no float16)."""
    b = np.int64(bits)
    sign = -1.0 if b & 0x8000 else 1.0
    e = (b >> 10) & 0x1F
    m = b & 0x3FF
    if e == 0:
        return sign * m * 2.0 ** -24
    if e == 31:
        return sign * np.inf if m == 0 else np.nan
    return sign * (1024 + m) * 2.0 ** (e - 25)


@njit(cache=True, parallel=True)
def map_stats(bits, filled, off, mean, spread, count):
    """Per map c (texels off[c]:off[c + 1] of the half floats `bits`):
    its filled texels' count, mean (summed in texel order) and spread (the
    largest channel's max - min; 0 if none filled)."""
    for c in prange(len(off) - 1):
        s0 = s1 = s2 = 0.0
        lo0 = lo1 = lo2 = np.inf
        hi0 = hi1 = hi2 = -np.inf
        n = 0
        for k in range(off[c], off[c + 1]):
            if filled[k]:
                n += 1
                v0, v1, v2 = half_value(bits[k, 0]), half_value(bits[k, 1]), half_value(bits[k, 2])
                s0, s1, s2 = s0 + v0, s1 + v1, s2 + v2
                lo0, lo1, lo2 = min(lo0, v0), min(lo1, v1), min(lo2, v2)
                hi0, hi1, hi2 = max(hi0, v0), max(hi1, v1), max(hi2, v2)
        count[c] = n
        d = max(n, 1)
        mean[c, 0], mean[c, 1], mean[c, 2] = s0 / d, s1 / d, s2 / d
        spread[c] = max(hi0 - lo0, hi1 - lo1, hi2 - lo2) if n else 0.0


def _single_colour(stored, filled, off):
    """Per map (texels off[c]:off[c + 1] of `stored`): the mean (nc, 3)
    float64 of its filled texels, and whether it is of a single colour
    (its filled texels' spread within CONSTANT_REL of the brightest
    channel's mean, or none filled: mean 0). One kernel over the maps: a
    per-triangle layout has a hundred thousand, and numpy's passes over
    every texel cost half a second."""
    nc = len(off) - 1
    mean = np.zeros((nc, 3))
    spread = np.zeros(nc)
    count = np.zeros(nc, np.int64)
    map_stats(stored.view(np.uint16), filled, np.asarray(off, np.int64), mean, spread, count)
    return mean, (count == 0) | (spread <= CONSTANT_REL * mean.max(axis=1))


@njit(cache=True, parallel=True)
def place_maps(pages, bits, flat_bits, off, unique, constant, page, x0, y0, usize, peak):
    """Map unique[u] (half floats: texels from off[c] of `bits`, or its one
    colour flat_bits[c] where constant) into pages[page[u]] at (x0[u],
    y0[u]), usize[u] texels square; peak[u] its brightest channel."""
    for u in prange(len(unique)):
        c = unique[u]
        s = usize[u]
        top = np.float32(0.0)
        for j in range(s):
            for i in range(s):
                for ch in range(3):
                    v = np.float32(half_value(flat_bits[c, ch] if constant[c] else bits[off[c] + j * s + i, ch]))
                    pages[page[u], y0[u] + j, x0[u] + i, ch] = v
                    top = max(top, v)
        peak[u] = top


def build_atlas(values, filled, charts, emitter_chart) -> Lightmaps:
    """values (N, 3) float64 texels of every chart (flat, charts.offsets);
    filled (N,) bool the texels that hold a value (the rest are 0 and
    never read); emitter_chart (nc,) bool charts of emitting triangles
    (left out of the page scale)."""
    off = charts.offsets
    sizes = charts.size.astype(np.int64)
    stored = to_stored(values)
    mean, constant = _single_colour(stored, np.asarray(filled, bool), off)
    flat = np.repeat(mean.astype(np.float16)[:, None, :], MIN_SIZE * MIN_SIZE, axis=1)   # single-colour maps
    maps = [flat[c] if constant[c] else stored[off[c]:off[c + 1]] for c in range(len(sizes))]
    size = np.where(constant, MIN_SIZE, sizes)
    # deduplication: hash, then exact compare
    rep = np.empty(len(sizes), np.int64)
    unique, buckets = [], {}
    for c, m in enumerate(maps):
        data = m.tobytes()
        key = (int(size[c]), hashlib.blake2b(data, digest_size=8).digest())
        for u in buckets.get(key, ()):
            if maps[unique[u]].tobytes() == data:
                rep[c] = u
                break
        else:
            rep[c] = len(unique)
            buckets.setdefault(key, []).append(len(unique))
            unique.append(c)
    usize = size[unique]
    page, x0, y0, n_pages = pack_quadtree(usize)
    pages = np.zeros((n_pages, PAGE, PAGE, 3), np.float32)
    scale = np.zeros(n_pages, np.float32)
    uc = np.asarray(unique, np.int64)
    peak = np.zeros(len(uc), np.float32)
    # one kernel over the maps: a loop over 35,000 of them in Python cost half a second
    place_maps(pages, stored.view(np.uint16), mean.astype(np.float16).view(np.uint16), np.asarray(off, np.int64),
               uc, constant, page, x0, y0, usize.astype(np.int64), peak)
    lit = np.zeros(len(unique), bool)  # a map any non-emitter chart uses
    lit[rep[~emitter_chart]] = True
    u_lit = np.nonzero(lit)[0]
    np.maximum.at(scale, page[u_lit], peak[u_lit])
    for p in range(n_pages):  # a page of emitters only: scale by its own texels
        if scale[p] <= 0:
            scale[p] = float(pages[p].max())
    r = rep
    chart_uv = np.empty((len(sizes), 3, 2), np.float32)
    corner = np.where(constant[:, None, None], MIN_SIZE / 2.0, charts.corners2d)
    chart_uv[..., 0] = (x0[r][:, None] + corner[..., 0]) / PAGE
    chart_uv[..., 1] = (y0[r][:, None] + corner[..., 1]) / PAGE
    counts = {"maps": len(sizes), "unique": len(unique), "constant": int(constant.sum()),
              "texels": int(charts.texel_count), "texels_stored": int((usize ** 2).sum()), "pages": int(n_pages)}
    return Lightmaps(pages, page[r].astype(np.int32), chart_uv, scale, counts)
