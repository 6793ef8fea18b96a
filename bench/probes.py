"""Irradiance probes: count, time and bytes per scene and preset, and the
viewer's frame time with a sphere lit by them.

    python bench/probes.py [--scenes cornell_box,walkthrough] [--presets preview,default | ''] [--accuracy] [--window]
                           [--json]

Per scene and preset: the solve (as the bake does it), then the probe
stage alone (bake_probes, timed twice, the faster kept), the grid, the
share of valid probes and the bytes the probe block adds to the bake
file. With --accuracy: at default, the irradiance of probes clear of
surfaces and of the grid interpolated at random points as clear, against
the path tracer, for the 14 normals of a cube's faces and corners: a
probe's own map ("map"), the probe's map without the sun, punctual
lights and lamps with those added at the probe ("lit", as the viewer
reads a probe), and the points lit so (as the viewer lights objects).
With
--window: voxview's window under Xvfb (llvmpipe) at 1280x720
on the scene's default bake, with and without a sphere dropped at the
first frame, standing still or moved by the arrow keys every frame
(right and left in turn), and with a dynamic mesh (a copy of the scene
with an icosphere of 2,562 vertices, a sixth of the scene's height
across, 1.5 scene-heights ahead of the first camera, baked with
--dynamic ball) standing or moved the same way: the rate over 600
frames, and the steady rate from the difference between runs of 60 and
600 frames (the first drop builds the scene's BVH for the sphere's
visibility test and its shader).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

from common import emit


def probe_rows(scenes, presets):
    from baker.presets import bake_config
    from baker.probes import bake_probes, grid_for
    from baker.scene import load_scene, prepare
    from baker.solve import solve
    rows = []
    for name in scenes:
        scene = load_scene(name)
        prepared = prepare(scene)
        for preset in presets:
            cfg = bake_config(preset)
            t0 = time.perf_counter()
            solution = solve(prepared, cfg.solver)
            t_solve = time.perf_counter() - t0
            lo, hi = scene.bounds()
            grid = grid_for(lo, hi, cfg.probes.spacing, cfg.probes.budget)
            times = []
            for _ in range(2):
                t0 = time.perf_counter()
                probes = bake_probes(prepared, solution, grid, cfg.probes.rays, cfg.solver.seed)
                times.append(time.perf_counter() - t0)
            # the block's bytes as the file stores them: float32 SH and distances, float16 irradiance, uint8 validity
            size = probes.sh.nbytes + probes.irradiance.size * 2 + probes.depth.nbytes + probes.valid.size
            rows.append([name, preset, f"{probes.count:,}", " x ".join(str(int(d)) for d in probes.dims),
                         f"{probes.spacing:.3g}", f"{probes.valid.mean():.0%}", probes.rays, f"{t_solve:.1f}",
                         f"{min(times):.2f}", f"{size / 2 ** 20:.2f}"])
            del solution, probes
    return rows


FRAMES_SHORT, FRAMES_LONG = 60, 600
SWING = 20   # frames the moving sphere goes one way before it turns


def swing(frames):
    """Arrow-key events that move the sphere right and left in turn from
    frame 2 on, SWING frames each way, so that it stays in view (the
    window's script runs at a fixed 1/30 s a frame)."""
    events = []
    for k, start in enumerate(range(2, frames, SWING)):
        key = "RIGHT" if k % 2 == 0 else "LEFT"
        events += [{"frame": start, "key": key, "action": "press"},
                   {"frame": min(start + SWING, frames) - 1, "key": key, "action": "release"}]
    return events


def with_ball(name, folder) -> str:
    """A copy of the scene `name` with a node 'ball' (an icosphere of 2,562
    vertices, a sixth of the scene's height across) 1.5 heights ahead of
    its first camera: the path of the copy."""
    import pygltflib

    from baker.scene import camera_for, load_scene
    from baker.scene.load import resolve
    from scenes.generate import icosphere
    scene = load_scene(name)
    lo, hi = scene.bounds()
    cam = camera_for(scene, None)
    r = (hi[1] - lo[1]) / 12
    centre = np.asarray(cam.position) + 1.5 * (hi[1] - lo[1]) * np.asarray(cam.forward)
    doc = pygltflib.GLTF2().load(resolve(name))
    blob = bytearray(doc.binary_blob() or b"")
    pos, tri = icosphere(4, r)
    arrays = [(pos.astype(np.float32), "VEC3", 34962), ((pos / r).astype(np.float32), "VEC3", 34962),
              (tri.astype(np.uint32).reshape(-1), "SCALAR", 34963)]
    acc = []
    for arr, kind, target in arrays:
        while len(blob) % 4:
            blob.append(0)
        doc.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=len(blob), byteLength=arr.nbytes,
                                                    target=target))
        blob.extend(arr.tobytes())
        a = pygltflib.Accessor(bufferView=len(doc.bufferViews) - 1, count=len(arr),
                               componentType=5126 if arr.dtype == np.float32 else 5125, type=kind)
        if kind == "VEC3" and not acc:
            a.min, a.max = arr.min(axis=0).tolist(), arr.max(axis=0).tolist()
        doc.accessors.append(a)
        acc.append(len(doc.accessors) - 1)
    doc.materials.append(pygltflib.Material(name="ball", pbrMetallicRoughness=pygltflib.PbrMetallicRoughness(
        baseColorFactor=[0.8, 0.8, 0.8, 1.0], metallicFactor=0.0, roughnessFactor=1.0)))
    doc.meshes.append(pygltflib.Mesh(name="ball", primitives=[pygltflib.Primitive(
        attributes=pygltflib.Attributes(POSITION=acc[0], NORMAL=acc[1]), indices=acc[2],
        material=len(doc.materials) - 1)]))
    doc.nodes.append(pygltflib.Node(name="ball", mesh=len(doc.meshes) - 1, translation=centre.tolist()))
    doc.scenes[doc.scene or 0].nodes.append(len(doc.nodes) - 1)
    doc.buffers[0].byteLength = len(blob)
    doc.set_binary_blob(bytes(blob))
    path = os.path.join(folder, f"{name}_ball.glb")
    doc.save_binary(path)
    return path


def window_rows(scenes):
    rows = []
    if not shutil.which("xvfb-run"):
        return [["-", "Xvfb not installed", "-", "-"]]
    with tempfile.TemporaryDirectory() as d:
        for name in scenes:
            bake = os.path.join(d, f"{name}.glb")
            subprocess.run([sys.executable, "-m", "baker", "bake", name, "-o", bake], check=True,
                           capture_output=True)
            dynamic = os.path.join(d, f"{name}_dynamic.glb")
            subprocess.run([sys.executable, "-m", "baker", "bake", with_ball(name, d), "--dynamic", "ball", "-o",
                            dynamic], check=True, capture_output=True)
            for label, script, file in (("no object", [], bake), ("sphere", [{"frame": 1, "key": "O"}], bake),
                                        ("sphere moving", [{"frame": 1, "key": "O"}] + swing(FRAMES_LONG), bake),
                                        ("dynamic mesh", [], dynamic),
                                        ("dynamic mesh moving", swing(FRAMES_LONG), dynamic)):
                path = os.path.join(d, "s.json")
                with open(path, "w") as f:
                    json.dump(script, f)
                seconds = {}
                for frames in (FRAMES_SHORT, FRAMES_LONG):
                    r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x720x24", sys.executable, "-m",
                                        "viewer", file, "--script", path, "--frames", str(frames), "--width", "1280",
                                        "--height", "720"], capture_output=True, text=True, timeout=900)
                    last = [line for line in r.stdout.splitlines() if "frames in" in line]
                    if not last:
                        raise SystemExit(r.stderr)
                    seconds[frames] = float(last[-1].split(" in ")[1].split(" s")[0])
                steady = (FRAMES_LONG - FRAMES_SHORT) / (seconds[FRAMES_LONG] - seconds[FRAMES_SHORT])
                rows.append([name, label, f"{FRAMES_LONG / seconds[FRAMES_LONG]:.1f}", f"{steady:.1f}"])
    return rows


CUBE_NORMALS = np.array([v for a in range(3) for v in (np.eye(3)[a], -np.eye(3)[a])]
                        + [np.array([x, y, z]) / 3 ** 0.5 for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
PICKED = 12   # probes and random points per scene


def _errors(got, want):
    """|got - want| / (want + 2% of the brightest), per normal: a normal that
    sees almost nothing (out of the Cornell box's open front) is measured
    against the point's light, not its own tiny value."""
    return np.abs(got - want) / (want + 0.02 * want.max())


def _clear_points(prepared, points, reach):
    """Points whose 14 cube-normal rays meet nothing within `reach` and no
    back face at all (not inside an object)."""
    from baker.kernels.traverse import closest_hit_batch
    n = len(CUBE_NORMALS)
    o = np.repeat(points, n, 0)
    d = np.tile(CUBE_NORMALS, (len(points), 1))
    t, tri, _, _ = closest_hit_batch(prepared.bvh.arrays, o, d, 0.0, np.full(len(o), np.inf))
    corners = prepared.scene.triangle_corners()[np.maximum(tri, 0)]
    facing = np.einsum("ij,ij->i", np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), d)
    back = (tri >= 0) & (facing > 0)
    return ((t > reach) & ~back).reshape(len(points), n).all(axis=1)


def accuracy_rows(scenes):
    """Per scene at default: the irradiance maps of probes that see no
    surface nearer than a voxel cell, and the grid interpolated at random
    points as clear, against the path tracer's irradiance (65,536
    directions, one path each: 8,192 x 4 are themselves off by up to 4-8%
    beside a lamp) for the 14 normals of a cube's faces and corners."""
    from baker.presets import bake_config
    from baker.probes import bake_probes, grid_for, interpolate
    from baker.probes.sample import irradiance_map_at, probe_lights
    from baker.render.irradiance import path_traced_irradiance
    from baker.scene import load_scene, prepare
    from baker.solve import solve
    rows = []
    n = len(CUBE_NORMALS)
    for name in scenes:
        scene = load_scene(name)
        prepared = prepare(scene)
        cfg = bake_config("default")
        solution = solve(prepared, cfg.solver)
        lo, hi = scene.bounds()
        g = bake_probes(prepared, solution, grid_for(lo, hi, cfg.probes.spacing, cfg.probes.budget),
                        cfg.probes.rays, cfg.solver.seed)
        cell = float(solution.voxels.cell_size)
        pos = g.positions()
        rng = np.random.default_rng(7)
        clear = np.nonzero(g.valid & (g.depth[..., 0].reshape(g.count, -1).min(axis=1) > cell))[0]
        probe_err, viewer_err = [], []
        lights = probe_lights(g, prepared)   # the sun, punctual lights and lamps exact at the points, as in the viewer
        for i in rng.choice(clear, min(PICKED, len(clear)), replace=False):
            want = path_traced_irradiance(prepared, pos[i], CUBE_NORMALS, 65536, 1).sum(axis=1)
            got = irradiance_map_at(np.repeat(g.irradiance[i][None], n, 0), CUBE_NORMALS).sum(axis=1)
            probe_err.append(_errors(got, want))
            at = np.repeat(pos[i][None], n, 0)
            got = interpolate(g, at, CUBE_NORMALS, at, prepared.bvh.arrays, lights).sum(axis=1)
            viewer_err.append(_errors(got, want))
        candidates = lo + rng.random((40 * PICKED, 3)) * (hi - lo)
        points = candidates[_clear_points(prepared, candidates, cell)][:PICKED]
        point_err = []
        for p in points:
            want = path_traced_irradiance(prepared, p, CUBE_NORMALS, 65536, 1).sum(axis=1)
            got = interpolate(g, np.repeat(p[None], n, 0), CUBE_NORMALS, np.repeat(p[None], n, 0),
                              prepared.bvh.arrays, lights).sum(axis=1)
            point_err.append(_errors(got, want))
        pe, ve, qe = np.concatenate(probe_err), np.concatenate(viewer_err), np.concatenate(point_err)
        rows.append([name, f"{cell:.4g}", len(probe_err), f"{100 * np.median(pe):.1f}%",
                     f"{100 * np.mean(pe < 0.03):.0f}%", f"{100 * pe.max():.1f}%", f"{100 * np.median(ve):.1f}%",
                     f"{100 * np.mean(ve < 0.03):.0f}%", f"{100 * ve.max():.1f}%", len(point_err),
                     f"{100 * np.median(qe):.1f}%", f"{100 * np.mean(qe < 0.05):.0f}%", f"{100 * qe.max():.1f}%"])
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="cornell_box,walkthrough")
    ap.add_argument("--presets", default="preview,default,high", help="'' for none (the window alone)")
    ap.add_argument("--window", action="store_true")
    ap.add_argument("--accuracy", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    scenes = args.scenes.split(",")
    if args.presets:
        emit(args, "irradiance probes per scene and preset (probe stage alone, best of 2)",
             probe_rows(scenes, args.presets.split(",")),
             ["scene", "preset", "probes", "grid", "spacing", "valid", "rays", "solve s", "probes s", "MiB in file"])
    if args.accuracy:
        emit(args, f"probes against the path tracer at default, 14 normals each ({PICKED} probes and {PICKED} random "
                   "points per scene that see no surface nearer than a voxel cell)",
             accuracy_rows(scenes), ["scene", "cell", "probes", "map median", "map within 3%", "map max",
                                     "lit median", "lit within 3%", "lit max", "points", "median error", "within 5%",
                                     "max"])
    if args.window:
        emit(args, f"voxview window at 1280x720 under Xvfb (llvmpipe): {FRAMES_LONG} frames, and the steady rate "
                   f"(frames {FRAMES_SHORT} to {FRAMES_LONG}: after the first drop's BVH and shader)",
             window_rows(scenes), ["scene", "object", "fps over all", "fps steady"])


if __name__ == "__main__":
    main()
