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


def rel_rmse(image, ref, lamp, ref_noise=0.0):
    """Relative RMSE of luminance against a reference over the pixels no
    camera ray of the reference saw a lamp through (`lamp` mask), divided
    by the reference's mean there; the reference's own estimated noise
    (relative) subtracted in quadrature."""
    import math
    import numpy as np
    lum = np.array([0.2126, 0.7152, 0.0722])
    a = np.asarray(image, np.float64) @ lum
    r = np.asarray(ref, np.float64) @ lum
    keep = ~lamp
    m = r[keep].mean()
    mse = np.mean((a - r)[keep] ** 2) - (ref_noise * m) ** 2
    return math.sqrt(max(mse, 0.0)) / m


def cached_reference(name, scene, bvh, surf, cam, size, spp, seed=1000):
    """A path-traced reference (image, lamp mask, noise estimate, seconds),
    cached in bench/out keyed by scene name, size, spp and the scene file's
    hash."""
    import hashlib
    import numpy as np
    from baker.render.pathtrace import pathtrace
    from baker.scene.load import resolve
    digest = hashlib.sha256(open(resolve(name), "rb").read()).hexdigest()[:12]
    os.makedirs(os.path.join(ROOT, "bench", "out"), exist_ok=True)
    cache = os.path.join(ROOT, "bench", "out", f"pt_ref_{name}_{size}_{spp}_{digest}.npz")
    if os.path.exists(cache):
        z = np.load(cache)
        return z["image"], z["lamp"], float(z["noise"]), float(z["seconds"])
    r = pathtrace(bvh, surf, cam, size, size, spp, seed=seed)
    np.savez(cache, image=r.image, lamp=r.lamp, noise=r.noise, seconds=r.seconds)
    return r.image, r.lamp, r.noise, r.seconds
