"""Path tracer benchmark: samples per second, relative RMSE at 64/256/1024
spp against a converged image, the time to 1% on the Cornell box; the
time to 2% on the walkthrough scene; and, when a Python with Mitsuba 3 is
given, Mitsuba's figures on the same geometry, materials and camera,
measured against the same reference in the same way.

Error: relative RMSE of luminance over the pixels whose camera rays never
meet an emitter first (the lamp and its edge pixels out), divided by the
reference's mean there. The reference (cached in bench/out, keyed by
scene, size, spp and the scene file's hash) has noise of its own; its
estimate is subtracted in quadrature, so the figures are the images' own.

    python bench/pathtrace.py [--size 256] [--ref-spp 4096] [--mitsuba /path/to/python] [--json]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from common import cached_reference, emit, rel_rmse
from baker.scene import camera_for  # noqa: E402

MITSUBA_SCRIPT = r'''
import json, sys, time
import numpy as np
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
d = json.load(open(sys.argv[1]))
c = d["camera"]
p, f = np.array(c["position"]), np.array(c["forward"])
res = d["size"]
scene = {"type": "scene", "integrator": {"type": "path", "max_depth": -1},
         "sensor": {"type": "perspective", "fov_axis": "y", "fov": float(np.degrees(c["yfov"])),
                    "to_world": mi.ScalarTransform4f().look_at(origin=list(p), target=list(p + f), up=c["up"]),
                    "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"},
                             "pixel_format": "rgb"},
                    "sampler": {"type": "independent", "sample_count": 4}}}
for i, m in enumerate(d["materials"]):
    bsdf = {"type": "diffuse", "reflectance": {"type": "rgb", "value": m["albedo"]}}
    if m["double"]:
        bsdf = {"type": "twosided", "bsdf": bsdf}
    shape = {"type": "obj", "filename": m["file"], "face_normals": True, "bsdf": bsdf}
    if max(m["emission"]) > 0:
        shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": m["emission"]}}
    scene["s%d" % i] = shape
out = {}
for sampler in d["samplers"]:
    scene["sensor"]["sampler"] = {"type": sampler, "sample_count": 4}
    sc = mi.load_dict(scene)
    np.array(mi.render(sc, spp=4))  # compile
    for spp in d["spp"]:
        t = time.perf_counter()
        img = np.array(mi.render(sc, spp=spp, seed=1))
        dt = time.perf_counter() - t
        name = "%s/mi_%s_%d.npy" % (d["dir"], sampler, spp)
        np.save(name, img)
        out["%s %d" % (sampler, spp)] = [name, dt]
print(json.dumps(out))
'''


def export_for_mitsuba(scene, camera, folder):
    """One OBJ per material (face normals, the scene's winding) and a JSON
    of materials and camera."""
    corners = scene.triangle_corners()
    mats = []
    for i in range(len(scene.materials)):
        sel = np.nonzero(scene.material_ids == i)[0]
        if not len(sel):
            continue
        fn = os.path.join(folder, f"m{i}.obj")
        with open(fn, "w") as f:
            for t in sel:
                for c in corners[t]:
                    f.write("v %.9g %.9g %.9g\n" % tuple(c))
            for k in range(len(sel)):
                f.write(f"f {3 * k + 1} {3 * k + 2} {3 * k + 3}\n")
        mats.append({"file": fn, "albedo": scene.albedo[i].tolist(), "emission": scene.emission[i].tolist(),
                     "double": bool(scene.double_sided[i])})
    return {"materials": mats, "camera": {"position": list(map(float, camera.position)),
                                          "forward": list(map(float, camera.forward)),
                                          "up": list(map(float, camera.up)), "yfov": float(camera.yfov)}}


def time_to(target, spps, errors, seconds):
    """Seconds to reach `target` by a power law fitted to (spp, error),
    at the measured seconds per spp."""
    b, a = np.polyfit(np.log(spps), np.log(errors), 1)
    n = math.exp((math.log(target) - a) / b)
    return n * float(np.mean(np.array(seconds) / np.array(spps))), n


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", default="64,256,1024")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--mitsuba", metavar="PYTHON", help="a Python interpreter with mitsuba 3 installed")
    ap.add_argument("--walkthrough-size", type=int, default=128)
    ap.add_argument("--walkthrough-limit", type=float, default=400.0, help="seconds at most for the 2%% run")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    import baker
    from baker.render import camera_array
    from baker.render.pathtrace import pathtrace
    from baker.scene import build_scene_bvh, pack
    s = args.size
    spps = [int(x) for x in args.spp.split(",")]
    scene = baker.load_scene("cornell_box")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    camera = camera_for(scene, None, bvh)
    cam = camera_array(camera, s, s)
    pathtrace(bvh, surf, camera_array(camera, 8, 8), 8, 8, 4)  # compile
    ref, lamp, ref_noise, ref_s = cached_reference("cornell_box", scene, bvh, surf, cam, s, args.ref_spp)
    rows, errs, secs = [], [], []
    for n in spps:
        r = pathtrace(bvh, surf, cam, s, s, n, seed=1)
        e = rel_rmse(r.image, ref, lamp, ref_noise)
        errs.append(e)
        secs.append(r.seconds)
        rows.append(["voxgi", "Sobol (Owen)", n, f"{r.seconds:.2f}", f"{s * s * n / r.seconds / 1e6:.2f}",
                     f"{100 * e:.2f}", f"{100 * r.noise:.2f}"])
    t1, n1 = time_to(0.01, spps, errs, secs)
    summary = {"voxgi": (t1, n1)}
    if args.mitsuba:
        with tempfile.TemporaryDirectory() as tmp:
            d = export_for_mitsuba(scene, camera, tmp)
            d.update(size=s, spp=spps, samplers=["independent", "multijitter"], dir=tmp)
            with open(os.path.join(tmp, "scene.json"), "w") as f:
                json.dump(d, f)
            with open(os.path.join(tmp, "run.py"), "w") as f:
                f.write(MITSUBA_SCRIPT)
            res = subprocess.run([args.mitsuba, os.path.join(tmp, "run.py"), os.path.join(tmp, "scene.json")],
                                 capture_output=True, text=True, check=True)
            got = json.loads(res.stdout.strip().splitlines()[-1])
            for sampler in ("independent", "multijitter"):
                me, ms = [], []
                for n in spps:
                    name, dt = got[f"{sampler} {n}"]
                    img = np.load(name)
                    e = rel_rmse(img, ref, lamp, ref_noise)
                    me.append(e)
                    ms.append(dt)
                    rows.append(["Mitsuba 3", sampler, n, f"{dt:.2f}", f"{s * s * n / dt / 1e6:.2f}", f"{100 * e:.2f}",
                                 ""])
                summary[f"Mitsuba 3 {sampler}"] = time_to(0.01, spps, me, ms)
    emit(args, f"Path tracer, Cornell box {s}x{s} (reference {args.ref_spp} spp, its own noise "
               f"{100 * ref_noise:.2f}% subtracted)", rows,
         ["renderer", "sampler", "spp", "seconds", "M samples/s", "rel. RMSE %", "estimate %"])
    emit(args, "Time to 1% relative RMSE (power law fitted over the spp above)",
         [[k, f"{n:.0f}", f"{t:.1f}"] for k, (t, n) in summary.items()], ["renderer", "spp", "seconds"])
    # the walkthrough: time to 2% by the tracer's own estimate
    w = args.walkthrough_size
    scene = baker.load_scene("walkthrough")
    bvh, surf = build_scene_bvh(scene), pack(scene)
    wrows = []
    for cam_index in range(1):
        c = camera_for(scene, cam_index if scene.cameras else None, bvh)
        t = time.perf_counter()
        r = pathtrace(bvh, surf, camera_array(c, w, w), w, w, 1 << 20, seed=1, noise=0.02,
                      time_limit=args.walkthrough_limit)
        wrows.append([c.name, f"{w}x{w}", r.spp, f"{100 * r.noise:.2f}", r.stopped,
                      f"{time.perf_counter() - t:.1f}", f"{w * w * r.spp / r.seconds / 1e6:.2f}"])
    emit(args, "Walkthrough: time to 2% (the tracer's estimate, --noise 0.02)", wrows,
         ["camera", "size", "spp", "estimate %", "stopped by", "seconds", "M samples/s"])


if __name__ == "__main__":
    sys.exit(main())
