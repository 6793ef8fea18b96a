"""Stage 4, images: cameras and the image loop, the reference path tracer,
the direct view of the voxel solution, lightcuts frames, instant
radiosity, a bake's CPU view, and image files. frame.py holds the registry
of methods (METHODS) and the pipeline each runs."""
from __future__ import annotations

from .camera import camera_array
from .frame import METHODS, Frame, Method, RenderSettings, render_frame
from .images import read_exr, write_image


def render(scene, camera=None, width=512, height=512, method="pathtrace", spp=64, seed=0, solution=None,
           config=None, bvh=None, surfaces=None, lightcuts=None):
    """A linear radiance image (height, width, 3) float32 of `scene` seen by
    `camera` (a Camera, a name or an index; None: the scene's first or an
    automatic one) by one of METHODS: 'pathtrace' (the reference, `spp`
    paths per pixel), 'voxels' (the voxel solution shown directly:
    `solution`, or one solved here with `config`), 'lightcuts' (a quality
    frame over that solution's VPLs, `lightcuts` a LightcutsConfig,
    default: the default preset's), 'instant-radiosity', or 'lightmap'
    (`scene` a Bake). `scene` may be a Prepared (scene/prepared.py)."""
    from ..scene import camera_for, prepare
    from ..scene.model import Camera
    prepared = prepare(scene.scene if method == "lightmap" else scene, bvh, surfaces)
    cam = camera if isinstance(camera, Camera) else camera_for(prepared.scene, camera, prepared.bvh)
    settings = RenderSettings(method, width, height, spp, seed, solver=config, lightcuts=lightcuts)
    return render_frame(scene if method == "lightmap" else prepared, cam, settings, bvh=prepared.bvh,
                        surfaces=prepared.surfaces, solution=solution).image


__all__ = ["METHODS", "Frame", "Method", "RenderSettings", "camera_array", "read_exr", "render", "render_frame",
           "write_image"]
