"""Helpers shared by the benchmarks: machine line, tables, JSON output."""
from __future__ import annotations

import json
import os
import platform
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import numba
    return f"{cpu}, {os.cpu_count()} cores, numba {numba.__version__} ({numba.config.THREADING_LAYER} threads)"


def table(rows, headers) -> str:
    cells = [[str(c) for c in r] for r in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) if cells else len(h) for i, h in enumerate(headers)]
    out = ["| " + " | ".join(h.ljust(w) for h, w in zip(headers, widths)) + " |",
           "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
    out += ["| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |" for r in cells]
    return "\n".join(out)


def emit(args, title, rows, headers, extra=None):
    if getattr(args, "json", False):
        print(json.dumps({"title": title, "machine": machine(), "headers": headers, "rows": rows,
                          **(extra or {})}, indent=1, default=str))
    else:
        print(f"## {title}\n\nmachine: {machine()}\n")
        print(table(rows, headers))
        print()
