"""How the solver's threads behave on a shared machine.

numba's OpenMP pool spin-waits between parallel regions by default; the
propagation has a barrier per batch of families (thousands per bounce), so
with another busy process on the machine a spinning thread holds a core
that the late thread needs. This runs the same propagation (Cornell box,
one bounce) under each threading set-up, on a quiet machine and beside
one and two busy processes, in fresh processes:

    python bench/threads.py [--cells 96] [--radius 8] [--reps 3] [--json]

The set-up voxgi uses is the first row (baker/__init__.py sets it before
numba starts its threads, unless the user set these variables).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

from common import ROOT, emit

SETUPS = [
    ("as voxgi sets it (nothing set by the user)", {}),
    ("omp, OMP_WAIT_POLICY=ACTIVE", {"OMP_WAIT_POLICY": "ACTIVE"}),
    ("omp, OMP_WAIT_POLICY=PASSIVE", {"OMP_WAIT_POLICY": "PASSIVE"}),
    ("workqueue", {"NUMBA_THREADING_LAYER": "workqueue"}),
]

CHILD = r"""
import json, sys, time
import numpy as np
sys.path.insert(0, {root!r})
import baker
from baker.scene import load_scene
from baker.solve import LineSweeper, direction_set
from baker.voxels import voxelize
import numba
v = voxelize(load_scene("cornell_box"), {cells})
sw = LineSweeper(v)
d = direction_set({radius})
rad = np.random.default_rng(0).random((len(v), 3))
off = sw.offsets(d, 0, 2)
sw.gather(rad, d, off)
times = []
for _ in range({reps}):
    t0 = time.perf_counter()
    sw.gather(rad, d, off)
    times.append(time.perf_counter() - t0)
print(json.dumps({{"voxels": len(v), "directions": d.n_directions, "times": times,
                   "layer": numba.threading_layer()}}))
"""


def busy(n):
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cells", type=int, default=96)
    ap.add_argument("--radius", type=int, default=8)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    code = CHILD.format(root=ROOT, cells=args.cells, radius=args.radius, reps=args.reps)
    rows = []
    quiet = {}
    for load in (0, 1, 2):
        for name, env in SETUPS:
            hogs = busy(load)
            try:
                time.sleep(0.5)
                base = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "NUMBA_THREADING_LAYER")}
                out = subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True,
                                     text=True, check=True).stdout
            finally:
                for h in hogs:
                    h.kill()
            r = json.loads(out.strip().splitlines()[-1])
            best = min(r["times"])
            if load == 0:
                quiet[name] = best
            rows.append([name, r["layer"], load, r["voxels"], r["directions"], f"{best:.2f}",
                         f"{max(r['times']):.2f}", f"{best / quiet[name]:.2f}",
                         f"{r['voxels'] * r['directions'] / best / 1e6:.1f}"])
    emit(args, f"Propagation beside busy processes ({os.cpu_count()} cores)", rows,
         ["set-up", "layer", "busy processes", "voxels", "directions", "best s", "worst s", "x quiet",
          "M transfers/s"])


if __name__ == "__main__":
    main()
