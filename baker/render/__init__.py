"""Stage 4, images: cameras and the image loop, the reference path tracer,
the direct view of the voxel solution, and image files."""
from __future__ import annotations


from .camera import camera_array
from .images import read_exr, write_image

METHODS = ("pathtrace", "voxels", "lightcuts")


def render(scene, camera=None, width=512, height=512, method="pathtrace", spp=64, seed=0, solution=None,
           config=None, bvh=None, surfaces=None, progress=None, lightcuts=None):
    """A linear radiance image (height, width, 3) float32 of `scene` seen by
    `camera` (a Camera, a name or an index; None: the scene's first or an
    automatic one). method 'pathtrace' (the reference, `spp` paths per
    pixel), 'voxels' (the voxel solution shown directly: `solution`, or
    one solved here with `config`) or 'lightcuts' (a quality frame over
    that solution's VPLs, `lightcuts` a LightcutsConfig, default: the
    default preset's)."""
    from ..scene import build_scene_bvh, pack
    from ..scene.model import Camera
    bvh = bvh or build_scene_bvh(scene)
    surfaces = surfaces or pack(scene)
    cam = camera if isinstance(camera, Camera) else scene.camera(camera, bvh)
    cam_arr = camera_array(cam, width, height)
    if method == "pathtrace":
        from .pathtrace import render_pathtrace
        return render_pathtrace(bvh, surfaces, cam_arr, width, height, spp, seed, progress)
    if method == "voxels":
        from ..config import solver_config
        from ..solve import solve
        from .voxelview import render_voxels
        solution = solution or solve(scene, config or solver_config(), bvh=bvh, surfaces=surfaces)
        return render_voxels(bvh, surfaces, solution, cam_arr, width, height, progress)
    if method == "lightcuts":
        from ..config import solver_config
        from ..lights import build_lights, lightcuts_config
        from ..solve import solve
        from .lightcuts_frame import render_lightcuts
        lc = lightcuts or lightcuts_config("default")
        solution = solution or solve(scene, config or solver_config(), bvh=bvh, surfaces=surfaces)
        lights = build_lights(scene, solution, surfaces, lc, bvh)
        return render_lightcuts(bvh, surfaces, lights, cam_arr, width, height, lc.epsilon, lc.cap, progress)[0]
    from ..errors import VoxgiError
    raise VoxgiError(f"unknown method {method!r}; choose from {', '.join(METHODS)}")


__all__ = ["METHODS", "camera_array", "read_exr", "render", "write_image"]
