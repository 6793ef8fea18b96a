"""Loading the real architectural scenes (../shared/realscenes/big and any
files given): per scene, the load's wall time, its peak resident memory
(each scene loaded in a fresh process, so the figure is that load's own),
and the triangles in the file and after the clean-up (degenerate and
duplicate triangles dropped, coplanar overlaps cut), with the triangles
cut and those left whole.

    python bench/real_scenes.py [--runs N] [--json] [FILE ...]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

from common import ROOT, emit

BIG = os.path.join(ROOT, "..", "shared", "realscenes", "big")

CHILD = r"""
import json, re, sys, time, warnings
t = time.perf_counter()
from baker.scene import load_scene
t_import = time.perf_counter() - t
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    t = time.perf_counter()
    scene = load_scene(sys.argv[1])
    t_load = time.perf_counter() - t
notes = " ".join(str(w.message) for w in caught)
cut = re.search(r"cut the overlapping part out of (\d+)", notes)
whole = re.search(r"left (\d+) coplanar", notes)
print(json.dumps({"load_s": t_load, "import_s": t_import, "triangles": int(len(scene.triangles)),
                  "cut": int(cut.group(1)) if cut else 0, "whole": int(whole.group(1)) if whole else 0}))
"""

FILE_TRIANGLES = r"""
import sys
from baker.scene.gltf_read import read_gltf
from baker.scene.obj import read_obj
p = sys.argv[1]
parts = read_gltf(p) if p.endswith((".glb", ".gltf")) else read_obj(p)
print(len(parts["triangles"]))
"""


def run_child(code, path):
    """(stdout, peak resident MiB) of a fresh interpreter running `code`."""
    p = subprocess.Popen([sys.executable, "-c", code, path], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         cwd=ROOT)
    out = p.stdout.read()
    err = p.stderr.read()
    _, status, usage = os.wait4(p.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{path}: {err.decode().strip().splitlines()[-1]}")
    return out.decode(), usage.ru_maxrss / 1024


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="*", help="more scenes to load")
    ap.add_argument("--runs", type=int, default=3, help="loads per scene (the range is reported)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    files = sorted(os.path.join(BIG, f) for f in os.listdir(BIG) if f.endswith(".glb")) if os.path.isdir(BIG) \
        else []
    files += args.files
    if not files:
        raise SystemExit(f"no scenes: {BIG} is absent and no file was given")
    rows = []
    for path in files:
        n_file = int(run_child(FILE_TRIANGLES, path)[0])
        loads, peaks, info = [], [], None
        for _ in range(args.runs):
            out, peak = run_child(CHILD, path)
            info = json.loads(out)
            loads.append(info["load_s"])
            peaks.append(peak)
        rows.append([os.path.basename(path), f"{n_file:,}", f"{info['triangles']:,}", f"{info['cut']:,}",
                     f"{info['whole']:,}", f"{min(loads):.2f}-{max(loads):.2f}", f"{max(peaks):.0f}"])
    emit(args, "Loading real scenes (voxbake info's load: parse, validate, clean up)", rows,
         ["scene", "triangles in file", "triangles loaded", "cut", "left whole", "load s", "peak MiB"])


if __name__ == "__main__":
    main()
