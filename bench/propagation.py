"""Linear propagation throughput and scaling (issue: voxel solver).

- discrete rays (voxel-direction transfers) per second at about 1M voxels
  and r = 8, with 1 thread and all threads;
- time vs N (voxels) at fixed D, and vs D at fixed N, with the fitted
  log-log slopes (linear cost: slope ~1);
- peak memory per voxel during propagation: the process's peak resident
  memory during a full cache-method propagation (all solver arrays), over
  its resident memory before voxelization, per voxel;
- voxelization of the walkthrough scene at 512 cells.

    python bench/propagation.py [--quick] [--json]
"""
from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np

from common import ROOT, emit
from baker.presets import solver_config
from baker.solve.directions import direction_set
from baker.solve.propagate import LineSweeper
from baker.solve import solve
from baker.scene import load_scene
from baker.stats import release_freed_memory
from baker.voxels import voxelize


def rss_bytes(field="VmRSS"):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    return 0


def reset_peak():
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def time_gather(sw, n, r, reps=1):
    d = direction_set(r)
    rad = np.random.default_rng(0).random((n, 3))
    off = sw.offsets(d, 0, 2)
    best = np.inf
    for _ in range(reps):
        t0 = time.perf_counter()
        sw.gather(rad, d, off)
        best = min(best, time.perf_counter() - t0)
    return best, n * d.n_directions


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes (a smoke test of this script)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    threads = numba.config.NUMBA_NUM_THREADS
    cornell = load_scene(os.path.join(ROOT, "scenes", "cornell_box.glb"))
    # JIT warm-up outside every timing
    v = voxelize(cornell, 16)
    time_gather(LineSweeper(v), len(v), 2)

    big_res = 96 if args.quick else 384
    rows = []
    rss0 = rss_bytes()
    t0 = time.perf_counter()
    v = voxelize(cornell, big_res)
    t_vox = time.perf_counter() - t0
    release_freed_memory()  # as solve() does after voxelizing and after building the sweeper
    sw = LineSweeper(v)
    release_freed_memory()
    for th in sorted({1, threads}):
        numba.set_num_threads(th)
        dt, transfers = time_gather(sw, len(v), 8, reps=2)  # best of two: this VM's timings vary
        rows.append(["throughput", f"cornell {big_res} cells", len(v), direction_set(8).n_directions, th, f"{dt:.2f}",
                     f"{transfers / dt / 1e6:.1f}"])
    numba.set_num_threads(threads)
    # memory: a full cache-method propagation as solve() runs it (the sweeper, H, current, the
    # per-bounce arrays), from a fresh sweeper; the voxel set exists before and after it
    del sw
    release_freed_memory()
    config = solver_config("default", radius=8)
    cur = v.albedo * np.random.default_rng(1).random((len(v), 3))
    total = np.zeros_like(cur)
    release_freed_memory()
    reset_ok = reset_peak()
    base = rss_bytes()
    sw = LineSweeper(v)
    for k, r in enumerate(config.radii()[:4], start=2):
        d = direction_set(r)
        hk = sw.irradiance(cur, d, sw.offsets(d, 0, k))
        total += hk
        np.multiply(v.albedo, hk, out=cur)  # as solve() does
    peak = rss_bytes("VmHWM") if reset_ok else base
    prop_per_voxel = (peak - base) / len(v)
    per_voxel = (peak - rss0) / len(v)
    emit(args, f"Linear propagation throughput (one bounce, r = 8, {direction_set(8).n_directions} directions)", rows,
         ["what", "scene", "voxels", "directions", "threads", "seconds", "M transfers/s"])

    # scaling in N at fixed D, and in D at fixed N
    res_list = [24, 48, 96] if args.quick else [48, 96, 192, 384]
    rn, times_n, ns = [], [], []
    for res in res_list:
        vv = v if res == big_res else voxelize(cornell, res)
        s = sw if res == big_res else LineSweeper(vv)
        dt, tr = time_gather(s, len(vv), 4, reps=2 if len(vv) < 300_000 else 1)
        rn.append([res, len(vv), direction_set(4).n_directions, f"{dt:.3f}", f"{tr / dt / 1e6:.1f}"])
        ns.append(len(vv))
        times_n.append(dt)
    slope_n = np.polyfit(np.log(ns), np.log(times_n), 1)[0]
    emit(args, f"Time vs voxels (r = 4): log-log slope {slope_n:.3f}", rn,
         ["cells", "voxels", "directions", "seconds", "M transfers/s"])
    vd = voxelize(cornell, 64 if args.quick else 96)
    swd = LineSweeper(vd)
    rd, times_d, ds = [], [], []
    for r in ([2, 4, 8] if args.quick else [2, 4, 8, 16]):
        dt, tr = time_gather(swd, len(vd), r, reps=2)
        nd = direction_set(r).n_directions
        rd.append([r, nd, len(vd), f"{dt:.3f}", f"{tr / dt / 1e6:.1f}"])
        ds.append(nd)
        times_d.append(dt)
    slope_d = np.polyfit(np.log(ds), np.log(times_d), 1)[0]
    emit(args, f"Time vs directions ({len(vd)} voxels): log-log slope {slope_d:.3f}", rd,
         ["r", "directions", "voxels", "seconds", "M transfers/s"])

    emit(args, "Memory during propagation (cache method, 4 bounces from r = 8)",
         [[f"cornell {big_res} cells", len(v), f"{v.nbytes / len(v):.0f}", f"{sw.nbytes / len(v):.0f}",
           f"{prop_per_voxel:.0f}" if reset_ok else "n/a", f"{per_voxel:.0f}" if reset_ok else "n/a"]],
         ["scene", "voxels", "voxel set B/voxel", "propagation arrays B/voxel (computed)",
          "propagation peak B/voxel (measured)", "peak with voxel set and solver arrays B/voxel"])

    # the whole solve() as a user runs it: voxel set, photons, solver arrays, two propagated bounces
    del sw, swd, vd, cur, total, hk
    release_freed_memory()
    reset_ok = reset_peak()
    base = rss_bytes()
    t0 = time.perf_counter()
    sol = solve(cornell, solver_config("default", resolution=big_res, radius=8, max_bounces=3))
    t_solve = time.perf_counter() - t0
    peak = rss_bytes("VmHWM") if reset_ok else base
    ns_ = len(sol.voxels)
    emit(args, "solve() peak memory (Cornell box, 1M photons, bounces 1-3: r = 8 then 6)",
         [[f"cornell {big_res} cells", ns_, f"{t_solve:.1f}", f"{(peak - base) / 2**20:.0f}",
           f"{(peak - base) / ns_:.0f}" if reset_ok else "n/a"]],
         ["scene", "voxels", "seconds", "peak over the process before solve() MiB", "B/voxel"])
    del sol

    walk = load_scene(os.path.join(ROOT, "scenes", "walkthrough.glb"))
    res = 128 if args.quick else 512
    t0 = time.perf_counter()
    vw = voxelize(walk, res)
    tw = time.perf_counter() - t0
    emit(args, "Voxelization", [["walkthrough", len(walk.triangles), res, len(vw), f"{tw:.2f}",
                                 f"{vw.nbytes / 2**20:.0f}"],
                                ["cornell box", len(cornell.triangles), big_res, len(v), f"{t_vox:.2f}",
                                 f"{v.nbytes / 2**20:.0f}"]],
         ["scene", "triangles", "cells (longest axis)", "voxels", "seconds", "voxel MiB"])


if __name__ == "__main__":
    main()
