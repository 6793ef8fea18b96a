"""Where the bake's heavy work runs: the executor seam.

The bake is one coordinator process. Three of its stages hand pure tasks
to an executor and reduce the results themselves, in the tasks' order:
the photons (fixed blocks of photon indices, solve/photons.py), each
bounce's propagation (fixed blocks of direction families,
solve/propagate.py) and the texels. What a stage's tasks all read (the
BVH, the voxels, a bounce's radiosity) is shared once per worker
(`share`), and `map` returns the results in the items' order whichever
finished first, so the plain run (LocalExecutor, in this process) and a
run on any number of Dask workers (bake/cluster.py) compute the same sums
in the same order.

The texel stage (lightmap/values.py)
decides which points to shade and combines their values; the shading
itself (a lightcut over the VPLs at a point, the gather of bounced light
from the voxels) is a pure function of the point, its normal and what
every point shares (ShadeContext: BVH, surfaces, lights, voxel solution).
So the points of each call go out as tiles of `tile` points in their
order, and the results are put back in that order, whichever worker ran a
tile and whenever it finished. A point's value depends on nothing else in
its tile, so neither the tile size nor the worker count changes a bit of
the bake: the plain `voxbake bake` (LocalExecutor, in this process) and a
bake on any number of Dask workers (bake/cluster.py) write the same bytes.

With a TileStore (`--checkpoint`), each finished tile is stored under the
hash of its inputs, and a later run of the same bake (`--resume`) takes
the tiles it finds there instead of shading them.
"""
from __future__ import annotations

import hashlib
import time
import zipfile
from dataclasses import dataclass

import numpy as np

TILE = 4096   # points per tile: a few hundred milliseconds of shading, small against a bake's thousands of points


@dataclass(frozen=True)
class ShadeContext:
    """What every tile of a bake shares, sent to each worker once.

    sharp: the Lights whose cuts every texel takes (split_lights' sharp
    part, or all of them); smooth: the bounced part (None: none);
    solution: the voxel Solution (the gather's light; None: no gather);
    offset: the points' lift off their surface; epsilon: the cuts' error
    bound; gather_rays: rays per gathered point."""
    bvh: object
    surfaces: object
    sharp: object
    smooth: object | None
    solution: object | None
    offset: float
    epsilon: float
    gather_rays: int


@dataclass(frozen=True)
class Tile:
    """One task: the points `start`.. of a shading call, what to shade them
    with ("sharp" / "smooth": a lightcut over that part's lights with `cap`
    and `exact`, floors `floor` or none; "gather": the bounced light by
    the gather) and where (`valid`). number: the tile's place in the bake
    (its name in messages)."""
    number: int
    what: str
    points: np.ndarray
    normals: np.ndarray
    valid: np.ndarray
    floor: np.ndarray | None
    cap: int
    exact: bool

    def key(self) -> str:
        """The hash of everything the tile's result depends on besides the
        bake's context (its number excluded: the same points are the same
        result wherever they fall)."""
        h = hashlib.sha256(f"{self.what}|{self.cap}|{int(self.exact)}|{self.floor is None}".encode())
        for a in (self.points, self.normals, self.valid) + (() if self.floor is None else (self.floor,)):
            a = np.ascontiguousarray(a)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.data)
        return h.hexdigest()

    def describe(self) -> str:
        return f"tile {self.number} ({self.what} light at {len(self.points):,} points)"


@dataclass(frozen=True)
class TileResult:
    """values (n, 3) float64; cuts (n,) int64 (the cut size at each valid
    point, 0 elsewhere; zeros for the gather); rays: shadow rays traced."""
    values: np.ndarray
    cuts: np.ndarray
    rays: int


def versions(digest: str | None = None) -> dict:
    """What a worker must share with its coordinator for the same bytes:
    voxgi (its version and the hash of its sources: `digest`, or read
    now), numpy, numba and Python's minor version."""
    import platform

    import numba

    import baker
    from ..kernel_cache import source_digest
    digest = digest or source_digest()
    return {"voxgi": f"{baker.__version__} (sources {(digest or 'unreadable')[:12]})",
            "numpy": np.__version__, "numba": numba.__version__,
            "python": ".".join(platform.python_version_tuple()[:2])}


def version_mismatch(theirs: dict, ours: dict) -> str | None:
    """'voxgi 0.1.0 (...) against 0.1.1 (...)' for the first package that
    differs, None when none does."""
    for k, v in ours.items():
        if theirs.get(k) != v:
            return f"{k} {theirs.get(k, 'missing')} against the coordinator's {v}"
    return None


def run_tile(tile: Tile, ctx: ShadeContext) -> TileResult:
    """The pure task: a tile's light."""
    from ..lights import irradiance
    from ..scene.prepared import Prepared
    from ..solve.gather import gather_bounced
    if tile.what == "gather":
        values = gather_bounced(Prepared(None, ctx.bvh, ctx.surfaces), ctx.solution, tile.points, tile.normals,
                                ctx.offset, ctx.gather_rays)
        return TileResult(values, np.zeros(len(tile.points), np.int64), 0)
    light = ctx.sharp if tile.what == "sharp" else ctx.smooth
    values, cuts, rays = irradiance(light, ctx.bvh, ctx.surfaces, tile.points, tile.normals, tile.valid,
                                    ctx.offset, ctx.epsilon, tile.cap, exact=tile.exact, floor=tile.floor,
                                    analytic=True)
    return TileResult(values, np.where(tile.valid, cuts, 0), int(rays.sum()))


def run_task(item, fn=None, shared=(), versions=None, threads=0):
    """A task on a worker: fn(item, *shared) with `threads` numba threads
    (0: all it has), refused when the worker's versions are not the
    coordinator's (a worker that joined after the bake began included)."""
    import numba

    from ..errors import VoxgiError
    if versions:
        bad = version_mismatch(_own_versions(), versions)
        if bad:
            raise VoxgiError(f"a worker runs {bad}: install the same voxgi, numpy and numba on every worker")
    before = numba.get_num_threads()
    if threads:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    try:
        return fn(item, *shared)
    finally:
        numba.set_num_threads(before)


_OWN = []


def _own_versions() -> dict:
    """This process's versions, the sources' hash read once (the code it
    runs is what it loaded first)."""
    if not _OWN:
        from ..kernel_cache import source_digest
        _OWN.append(source_digest())
    return versions(_OWN[0])


class Executor:
    """Runs a bake's pure tasks (texel tiles; the solve's photon blocks
    and blocks of direction families): the base of the in-process and the
    Dask executors. `share(obj)` sends what many tasks read once and gives
    a handle; `map(fn, items, *handles)` runs fn(item, *shared) for each
    item and returns the results in the items' order, whichever finished
    first. Subclasses give `_share`, `_release` and `_run(fn, items,
    handles, name)` (yield (index, result) as tasks finish, in any order).
    counts: tasks run, tiles taken from the store, retries, bytes sent and
    received, seconds in transfer."""
    workers = 0          # 0: in this process

    def __init__(self, store=None, tile: int = TILE):
        self.store = store
        self.tile = int(tile)
        self.ctx = None
        self._ctx_handle = None
        self._numbered = 0
        self.counts = {"tasks": 0, "tiles_resumed": 0, "retries": 0, "bytes_sent": 0, "bytes_received": 0,
                       "transfer_seconds": 0.0}
        self.named = {}      # tasks run per kind ("tile", "pieces", "photons", "voxels", "families", "probes")

    def start(self):
        """A bake begins: a cluster checks its workers' versions."""

    def share(self, obj):
        """A handle on obj for map's tasks (sent to every worker once)."""
        return self._share(obj)

    def release(self, handle):
        """Lets the workers drop a shared object."""
        if handle is not None:
            self._release(handle)

    def map(self, fn, items, *handles, name="task", done=None, fold=None) -> list | None:
        """[fn(item, *shared) for item in items], the tasks run wherever
        this executor runs them; done(j, result) as item j is done (in
        any order). With fold, nothing is kept: fold(j, result) is called
        in the items' order as the results allow (and None returned).
        items: records with describe() (a failure's name)."""
        from ..startup import checkpoint
        results = None if fold else [None] * len(items)
        waiting, following = {}, 0
        checkpoint()
        for j, r in self._run(fn, items, handles, name):
            self.counts["tasks"] += 1
            self.named[name] = self.named.get(name, 0) + 1
            if done is not None:
                done(j, r)
            if fold is None:
                results[j] = r
            else:
                waiting[j] = r
                while following in waiting:
                    fold(following, waiting.pop(following))
                    following += 1
            checkpoint()
        return results

    def open(self, ctx: ShadeContext):
        """Shares the texel stage's context (the previous bake's let go)."""
        self.release(self._ctx_handle)
        self.ctx = ctx
        self._ctx_handle = self.share(ctx)

    def shade(self, what, points, normals, valid=None, floor=None, cap=0, exact=True, progress=None):
        """(values (n, 3), cuts (n,) at the valid points, shadow rays) for
        the points, tile by tile; progress(k) as the valid points of a
        tile are done."""
        n = len(points)
        valid = np.ones(n, bool) if valid is None else np.asarray(valid, bool)
        tiles = []
        for a in range(0, n, self.tile):
            b = slice(a, a + self.tile)
            tiles.append(Tile(self._numbered, what, np.ascontiguousarray(points[b], np.float64),
                              np.ascontiguousarray(normals[b], np.float64), np.ascontiguousarray(valid[b]),
                              None if floor is None else np.ascontiguousarray(floor[b], np.float64), int(cap),
                              bool(exact)))
            self._numbered += 1
        results = [None] * len(tiles)
        keys = [None] * len(tiles)
        todo = []
        for i, t in enumerate(tiles):
            if self.store is not None:
                keys[i] = t.key()
                results[i] = self.store.get(keys[i], len(t.points))
            if results[i] is None:
                todo.append(i)
            else:
                self.counts["tiles_resumed"] += 1
                if progress is not None:
                    progress(int(t.valid.sum()))

        def done(j, r):
            i = todo[j]
            if self.store is not None:
                self.store.put(keys[i], r)
            if progress is not None:
                progress(int(tiles[i].valid.sum()))
        shaded = self.map(run_tile, [tiles[i] for i in todo], self._ctx_handle, name="tile", done=done)
        for i, r in zip(todo, shaded):
            results[i] = r
        values = np.concatenate([r.values for r in results]) if results else np.zeros((0, 3))
        cuts = np.concatenate([r.cuts for r in results]) if results else np.zeros(0, np.int64)
        return values, cuts, sum(r.rays for r in results)

    def _share(self, obj):
        return obj

    def _release(self, handle):
        pass

    def _run(self, fn, items, handles, name):
        raise NotImplementedError

    def close(self):
        self.release(self._ctx_handle)
        self._ctx_handle = None

    def summary(self) -> str:
        """The summary table's row."""
        c = self.counts
        resumed = f", {c['tiles_resumed']:,} from the checkpoint" if c["tiles_resumed"] else ""
        kinds = f"{self.named.get('tile', 0):,} tiles of {self.tile:,} points{resumed}"
        for name, what in (("pieces", "buried-piece blocks"), ("photons", "photon blocks"), ("voxels", "voxel blocks"),
                           ("families", "blocks of directions"), ("probes", "probe blocks")):
            if self.named.get(name):
                kinds += f", {self.named[name]:,} {what}"
        if not self.workers:
            return f"in this process: {kinds}"
        return (f"{self.workers} ({self.where}): {c['tasks']:,} tasks ({kinds}), "
                f"{c['retries']} retries, {c['bytes_sent'] / 2 ** 20:.1f} MiB sent, "
                f"{c['bytes_received'] / 2 ** 20:.1f} MiB received, {c['transfer_seconds']:.2f} s in transfer")


class LocalExecutor(Executor):
    """The tasks one after another in this process, on its numba threads."""

    def _run(self, fn, items, handles, name):
        for j, item in enumerate(items):
            yield j, fn(item, *handles)


class TileStore:
    """A checkpoint folder: the solve's result and every finished tile of
    one bake, each file written whole or not at all (a temporary name,
    then a rename). identity: the hash of the scene's arrays and the
    bake's settings; a folder holding another identity is refused.
    resume False: a folder that holds a checkpoint is refused too (it
    would be mixed with this bake's)."""
    MANIFEST = "voxgi-checkpoint.json"

    def __init__(self, folder, identity: str, resume: bool):
        import json
        import os

        from ..errors import VoxgiError
        self.folder = os.path.abspath(folder)
        self.identity = identity
        manifest = os.path.join(self.folder, self.MANIFEST)
        if os.path.exists(self.folder) and not os.path.isdir(self.folder):
            raise VoxgiError("--checkpoint names a file, not a folder", folder)
        found = None
        if os.path.exists(manifest):
            try:
                with open(manifest) as f:
                    found = json.load(f)
                found = found.get("identity") if isinstance(found, dict) else None
            except (OSError, ValueError):
                raise VoxgiError("the checkpoint's manifest is unreadable: remove the folder", folder) from None
            if found != identity:
                raise VoxgiError("the checkpoint is of another scene or other settings: remove it or give another "
                                 "folder", folder)
            if not resume:
                raise VoxgiError("the folder already holds a checkpoint of this bake: add --resume to use it, or "
                                 "remove it", folder)
        elif resume and os.path.isdir(self.folder) and os.listdir(self.folder):
            raise VoxgiError("the folder holds no voxgi checkpoint: nothing to resume", folder)
        try:
            os.makedirs(os.path.join(self.folder, "tiles"), exist_ok=True)
            if found is None:
                self._write_bytes(manifest, json.dumps({"format": 1, "identity": identity}).encode())
        except OSError as e:
            raise VoxgiError(f"cannot write the checkpoint: {e.strerror}", folder) from None

    def _write_bytes(self, path, data: bytes):
        import os
        tmp = f"{path}.{os.getpid()}.tmp"
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)

    def _path(self, key):
        import os
        return os.path.join(self.folder, "tiles", key + ".npz")

    def get(self, key: str, n: int) -> TileResult | None:
        """The stored tile of n points, or None (absent, or not whole)."""
        try:
            with np.load(self._path(key), allow_pickle=False) as z:
                values, cuts, rays = z["values"], z["cuts"], z["rays"]
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
            return None
        if values.shape != (n, 3) or values.dtype != np.float64 or cuts.shape != (n,) or cuts.dtype != np.int64 \
                or rays.shape != () or not np.isfinite(values).all():
            return None   # damaged or not ours: shaded again
        return TileResult(values, cuts, int(rays))

    def put(self, key: str, r: TileResult):
        import io
        buf = io.BytesIO()
        np.savez(buf, values=r.values, cuts=r.cuts, rays=np.int64(r.rays))
        self._write_bytes(self._path(key), buf.getvalue())

    def get_solution(self):
        """The stored voxel Solution, or None."""
        import os

        from ..solve.cache_method import Solution
        from ..voxels.voxelize import Voxels
        from .records import read_record
        path = os.path.join(self.folder, "solution.npz")
        if not os.path.exists(path):
            return None
        return read_record(path, Solution, {"Voxels": Voxels})

    def put_solution(self, solution):
        import os

        from .records import record_bytes
        self._write_bytes(os.path.join(self.folder, "solution.npz"), record_bytes(solution))


def timed(counts, key="transfer_seconds"):
    """A context adding its seconds to counts[key]."""
    class _T:
        def __enter__(self):
            self.t = time.perf_counter()

        def __exit__(self, *exc):
            counts[key] += time.perf_counter() - self.t
    return _T()
