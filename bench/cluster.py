"""What predicts a bake's speed-up on many Dask workers, measured on this
machine (two cores cannot show one past 2).

    python bench/cluster.py [--scene walkthrough] [--densities default,6.944] [--workers 1,2] [--json]

For each texel density of the scene (`default`: the preset's, the
density users ship; a number: texels per unit, 6.944 the walkthrough's
old one-per-voxel-cell density):

1. A bake in this process on ONE numba thread, each task timed (texel
   tiles, photon blocks, the solver's voxel blocks or blocks of
   directions; the gathers split as for 32 workers): the serial part
   (everything but the tasks: load, BVH, voxelize, the photons' pilot and
   sums, the bounces' sums, charts, the texel stage's own orchestration,
   lights, atlas, write), the tasks' sum per kind, per map call (a
   barrier: the next call needs this one's results). The serial fraction
   s is the serial part over the whole.
2. Tile-size sweep: tasks, the largest task against the mean, and the
   speed-up that N one-core workers would give: Amdahl (1 / (s + (1 -
   s) / N)) and a schedule of the measured tiles (each call's tiles on N
   workers, longest first, calls one after another) plus the measured
   per-task overhead and the context's broadcast.
3. Measured bakes on a local cluster of 1 and 2 worker processes (one
   numba thread each), against the bake in this process on 1 and 2
   threads: wall time, texel stage, bytes sent and received, broadcast
   time, per-task overhead ((texel stage on 1 worker - texel stage here
   on one thread) / tiles).
"""
from __future__ import annotations

import argparse
import heapq
import time

from common import emit

PREDICT = (8, 32, 128)
STAGES = ("bvh", "voxelize", "photons", "propagation", "charts", "texels", "lights", "atlas")


def timed_executor(tile, split=32):
    from baker.bake.executor import LocalExecutor

    class Timed(LocalExecutor):
        """Tasks in this process, each task's seconds kept per map call
        (a barrier: the next call needs this one's results); the solver's
        gathers split as for `split` workers."""
        workers = split
        where = "this process, timed"

        def __init__(self):
            super().__init__(tile=tile)
            self.calls = []

        def _run(self, fn, items, handles, name):
            times = []
            self.calls.append((name, times))
            for j, item in enumerate(items):
                t0 = time.perf_counter()
                r = fn(item, *handles)
                times.append(time.perf_counter() - t0)
                yield j, r
    return Timed()


def bake_once(scene_name, density, executor, threads):
    """(wall seconds, texel-stage seconds, BakeResult): the whole bake as
    `voxbake bake` does it (load to written file)."""
    import os
    import tempfile

    from baker.bake import bake_config, bake_scene, write_bake
    from baker.scene import load_scene
    from baker.stats import Stats
    kw = {} if density == "default" else {"texel_density": float(density)}
    t0 = time.perf_counter()
    stats = Stats("bake")
    scene = load_scene(scene_name)
    result = bake_scene(scene, bake_config("default", threads=threads, **kw), stats, executor=executor)
    with tempfile.TemporaryDirectory() as d:
        write_bake(os.path.join(d, "b.glb"), result.bake)
    wall = time.perf_counter() - t0
    bake_once.stages = {k: v["seconds"] for k, v in stats.stages.items()}
    return wall, stats.stages["texels"]["seconds"], result


def makespan(calls, n, overhead=0.0):
    """Seconds for the calls' tiles on n workers: each call's tiles
    longest first onto the least-loaded worker (each tile plus `overhead`),
    the calls one after another."""
    total = 0.0
    for _, tiles in calls:
        loads = [0.0] * min(n, max(1, len(tiles)))
        heapq.heapify(loads)
        for t in sorted(tiles, reverse=True):
            heapq.heappush(loads, heapq.heappop(loads) + t + overhead)
        total += max(loads)
    return total


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="walkthrough")
    ap.add_argument("--densities", default="default,6.944")
    ap.add_argument("--tiles", default="1024,4096,16384", help="tile sizes of the sweep")
    ap.add_argument("--workers", default="1,2", help="local cluster sizes measured")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    from baker.bake.cluster import dask_executor
    from baker.bake.executor import TILE
    # warm: the kernels loaded once before anything is timed
    bake_once("cornell_box", "default", None, 1)
    sweep_rows, measured_rows, predict_rows, stage_rows = [], [], [], []
    for density in args.densities.split(","):
        # 3. measured: in this process on 1 and 2 threads, then on local clusters
        measured = {}
        for threads in (1, 2):
            wall, tex, res = bake_once(args.scene, density, None, threads)
            measured[f"this process, {threads} thread{'s' if threads > 1 else ''}"] = (wall, tex, None)
        for n in (int(w) for w in args.workers.split(",")):
            with dask_executor(workers=n) as ex:
                t0 = time.perf_counter()
                wall, tex, res = bake_once(args.scene, density, ex, 0)
                measured[f"{n} worker{'s' if n > 1 else ''} (local cluster)"] = \
                    (wall, tex, dict(ex.counts, tiles=ex.named.get("tile", 0)))
        # 1. and 2.: timed tiles on one thread, per tile size
        overhead = None
        for tile in (int(t) for t in args.tiles.split(",")):
            ex = timed_executor(tile)
            wall, tex, res = bake_once(args.scene, density, ex, 1)
            tiles = [t for _, c in ex.calls for t in c]
            kinds = {}
            for name, c in ex.calls:
                kinds[name] = kinds.get(name, 0.0) + sum(c)
            shading = sum(tiles)
            serial = wall - shading
            s = serial / wall
            mean = shading / max(1, len(tiles))
            if tile == TILE:
                one = measured.get("1 worker (local cluster)")
                if one is not None:   # the texel stage on one worker against the same stage here, per task
                    overhead = max(0.0, (one[1] - tex) / max(1, one[2]["tiles"]))
                    broadcast = one[2]["transfer_seconds"]
            row = [density, f"{res.counts['texel_size_asked']:.4g}", f"{res.texel_stats.points_shaded:,}", tile,
                   len(tiles), len(ex.calls), f"{wall:.1f}",
                   " ".join(f"{k} {v:.1f}" for k, v in kinds.items()), f"{s:.1%}",
                   f"{max(tiles) / mean:.1f}" if tiles else "-"]
            for n in PREDICT:
                amdahl = 1.0 / (s + (1.0 - s) / n)
                sched = wall / (serial + makespan(ex.calls, n))
                row.append(f"{amdahl:.1f} / {sched:.1f}")
            sweep_rows.append(row)
            if tile == TILE:
                base = (wall, serial, ex.calls, s)
                # where the serial part is: each stage less the tasks it ran
                in_stage = {"voxelize": kinds.get("pieces", 0.0), "photons": kinds.get("photons", 0.0),
                            "propagation": kinds.get("voxels", 0.0) + kinds.get("families", 0.0),
                            "texels": kinds.get("tile", 0.0)}
                stages = bake_once.stages
                outside = wall - sum(stages.values())
                stage_rows.append([density] + [f"{stages.get(k, 0.0) - in_stage.get(k, 0.0):.2f}"
                                               + (f" ({in_stage[k]:.1f})" if k in in_stage else "")
                                               for k in STAGES] + [f"{outside:.2f}", f"{serial:.1f}"])
        wall1, serial1, calls1, s1 = base
        for name, (wall, tex, counts) in measured.items():
            measured_rows.append([density, name, f"{wall:.1f}", f"{tex:.1f}", f"{wall1 / wall:.2f}",
                                  "-" if counts is None else counts["tasks"],
                                  "-" if counts is None else f"{counts['bytes_sent'] / 2 ** 20:.1f}",
                                  "-" if counts is None else f"{counts['bytes_received'] / 2 ** 20:.1f}",
                                  "-" if counts is None else f"{counts['transfer_seconds']:.2f}"])
        if overhead is not None:
            row = [density, f"{s1:.1%}", f"{1000 * overhead:.1f}", f"{broadcast:.2f}"]
            for n in PREDICT:
                row.append(f"{wall1 / (serial1 + broadcast + makespan(calls1, n, overhead)):.1f}")
            predict_rows.append(row)
    head = ["density", "texel", "points shaded", "tile", "tasks", "calls", "1-thread s", "task s by kind", "serial",
            "max/mean task"] + [f"x{n} Amdahl / sched" for n in PREDICT]
    emit(args, f"{args.scene}: serial fraction and tile sweep (one thread; speed-ups over it)", sweep_rows, head)
    emit(args, f"{args.scene}: the serial part by stage, one thread, seconds (in brackets: the stage's tasks)",
         stage_rows, ["density"] + list(STAGES) + ["load + write", "serial"])
    emit(args, f"{args.scene}: measured bakes (speed-up over this process on 1 thread, tile {TILE})", measured_rows,
         ["density", "run", "wall s", "texels s", "speed-up", "tasks", "MiB sent", "MiB received",
          "transfer s"])
    emit(args, f"{args.scene}: predicted speed-up with the measured per-task overhead and broadcast (tile {TILE})",
         predict_rows, ["density", "serial", "overhead ms/task", "broadcast s"] + [f"x{n}" for n in PREDICT])


if __name__ == "__main__":
    main()
