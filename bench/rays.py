"""Ray-tracing core throughput: BVH build time and Mrays/s for closest-hit
and shadow (any-hit) queries, coherent (camera) and incoherent (random
surface points, random directions) rays, on the Cornell box, a bunny-sized
mesh (a displaced icosphere, 82k triangles, in a room) and the walkthrough
scene; side by side with Embree (embreex, single-threaded batch) when it is
installed. Ours is timed with 1 thread (per core, like Embree's batch call)
and with all threads.

    python bench/rays.py [--rays N] [--json]
"""
from __future__ import annotations

import argparse
import time
import warnings

import numba
import numpy as np

from common import ROOT, emit
from baker.scene import camera_for  # noqa: E402
from baker.errors import VoxgiWarning
from baker.scene import bvh as bvh_mod
from baker.render import camera_array
from baker.scene import load_scene


def bunny_sized(path):
    from scenes.generate import GltfBuilder, box, icosphere
    b = GltfBuilder()
    pos, tri = icosphere(6, 0.5, (0, 0.6, 0))
    rng = np.random.default_rng(0)
    dirs = (pos - [0, 0.6, 0]) / 0.5
    bump = 1 + 0.08 * np.sin(7 * dirs[:, 0]) * np.cos(5 * dirs[:, 1]) + 0.01 * rng.random(len(pos))
    pos = (pos - [0, 0.6, 0]) * bump[:, None] + [0, 0.6, 0]
    m = b.material("m", (0.7, 0.7, 0.7))
    b.mesh("bunny", pos, tri, m)
    b.mesh("room", *box((-1.5, 0, -1.5), (1.5, 2, 1.5), inward=True), m)
    b.camera("front", (0, 0.8, -1.4), (0, -0.1, 1), yfov_deg=60)
    b.save(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", VoxgiWarning)  # no lamp: rays only
        return load_scene(path)


def surface_points(scene, n, rng):
    c = scene.triangle_corners()
    a = scene.triangle_areas()
    t = rng.choice(len(a), n, p=a / a.sum())
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    p = c[t, 0] + u[:, None] * (c[t, 1] - c[t, 0]) + v[:, None] * (c[t, 2] - c[t, 0])
    n = np.cross(c[t, 1] - c[t, 0], c[t, 2] - c[t, 0])
    return p, n / np.linalg.norm(n, axis=1, keepdims=True)


def offset(p, n, d, eps):
    """Move p off its surface along the normal, to the side d points to."""
    side = np.sign(np.einsum("ij,ij->i", n, d))[:, None]
    side[side == 0] = 1
    return p + n * side * eps


def ray_sets(scene, tree, n, rng):
    side = int(np.sqrt(n))
    cam = camera_array(camera_for(scene), side, side)
    ys, xs = np.mgrid[0:side, 0:side]
    a = 2 * (xs.ravel() + 0.5) / side - 1
    b = 1 - 2 * (ys.ravel() + 0.5) / side
    d = cam[1] + a[:, None] * cam[2] + b[:, None] * cam[3]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.tile(cam[0], (len(d), 1))
    scale = float(np.abs(scene.vertices).max())
    t, _, _, _ = tree.closest(o, d)
    hit = np.isfinite(t)
    hp = o[hit] + d[hit] * t[hit, None]
    lo, hi = scene.bounds()
    target = (lo + hi) / 2 + [0, 0.45 * (hi - lo)[1], 0]
    sd = target - hp
    sdist = np.linalg.norm(sd, axis=1)
    sd /= sdist[:, None]
    eps = 1e-6 * scale
    po, pn = surface_points(scene, n, rng)
    rd = rng.normal(size=(n, 3))
    rd /= np.linalg.norm(rd, axis=1, keepdims=True)
    q, qn = surface_points(scene, n, rng)
    qd = q - po
    po2 = offset(po, pn, qd, eps)
    q2 = offset(q, qn, -qd, eps)
    qd = q2 - po2
    qdist = np.linalg.norm(qd, axis=1)
    ok = qdist > 1e-9
    qd = qd[ok] / qdist[ok, None]
    return {
        "closest coherent": (o, d, np.full(len(d), np.inf)),
        "closest incoherent": (offset(po, pn, rd, eps), rd, np.full(n, np.inf)),
        "shadow coherent": (hp + sd * eps, sd, sdist - 2 * eps),
        "shadow incoherent": (po2[ok], qd, qdist[ok]),
    }


def time_ours(tree, kind, o, d, tmax, threads):
    numba.set_num_threads(threads)
    fn = tree.closest if kind.startswith("closest") else tree.occluded
    fn(o[:64], d[:64], tmax=tmax[:64])
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        fn(o, d, tmax=tmax)
        best = min(best, time.perf_counter() - t0)
    return len(o) / best / 1e6


def time_embree(scene, sets, tree):
    try:
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        return None, {}, {}
    t0 = time.perf_counter()
    es = rtcs.EmbreeScene()
    TriangleMesh(es, scene.vertices[scene.triangles].astype(np.float32))
    es.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))  # Embree builds lazily on first query
    build = time.perf_counter() - t0
    out, agree = {}, {}
    for kind, (o, d, tmax) in sets.items():
        o32, d32 = o.astype(np.float32), d.astype(np.float32)
        best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            if kind.startswith("closest"):
                es.run(o32, d32, output=1)
            else:
                # embreex's occlusion query has no per-ray tfar: use dists
                es.run(o32, d32, query="OCCLUDED", dists=tmax.astype(np.float32))
            best = min(best, time.perf_counter() - t0)
        out[kind] = len(o) / best / 1e6
        # agreement on what was hit / occluded (float32 Embree vs our float64 arithmetic)
        if kind.startswith("closest"):
            ours = tree.closest(o, d, tmax=tmax)[1]
            theirs = np.asarray(es.run(o32, d32))
            agree[kind] = float(np.mean((ours >= 0) == (theirs >= 0)))
        else:
            ours = tree.occluded(o, d, tmax=tmax)
            theirs = np.asarray(es.run(o32, d32, query="OCCLUDED", dists=tmax.astype(np.float32)))
            agree[kind] = float(np.mean(ours == (theirs == 0)))
    return build, out, agree


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    import os
    import tempfile
    rng = np.random.default_rng(1)
    all_threads = numba.config.NUMBA_NUM_THREADS
    scenes = [("cornell box", load_scene(os.path.join(ROOT, "scenes", "cornell_box.glb"))),
              ("bunny-sized", bunny_sized(os.path.join(tempfile.mkdtemp(), "bunny.glb"))),
              ("walkthrough", load_scene(os.path.join(ROOT, "scenes", "walkthrough.glb")))]
    rows = []
    bvh_mod.build_scene_bvh(scenes[0][1])  # JIT warm-up outside the timings
    for name, scene in scenes:
        t0 = time.perf_counter()
        tree = bvh_mod.build_scene_bvh(scene)
        build = time.perf_counter() - t0
        sets = ray_sets(scene, tree, args.rays, rng)
        e_build, e, agree = time_embree(scene, sets, tree)
        for kind, (o, d, tmax) in sets.items():
            one = time_ours(tree, kind, o, d, tmax, 1)
            many = time_ours(tree, kind, o, d, tmax, all_threads)
            er = e.get(kind)
            rows.append([name, len(scene.triangles), f"{build:.3f}", kind, f"{one:.2f}", f"{many:.2f}",
                         f"{er:.2f}" if er else "-", f"{one / er:.2f}" if er else "-",
                         f"{e_build:.3f}" if e_build is not None else "-",
                         f"{agree[kind]:.4f}" if kind in agree else "-"])
    numba.set_num_threads(all_threads)
    emit(args, "Ray tracing core: Mrays/s", rows,
         ["scene", "triangles", "build s", "rays", "ours 1 thr", f"ours {all_threads} thr", "Embree 1 thr",
          "ours/Embree per core", "Embree build s", "agree"])


if __name__ == "__main__":
    main()
