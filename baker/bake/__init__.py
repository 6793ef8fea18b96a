"""Stage 6, the bake: scene -> voxel solution -> lightmaps -> bake file.

    bake = bake_scene(scene, bake_config("preview"))
    write_bake("out.glb", bake)
    image = render_bake(read_bake("out.glb"), camera=0)
"""
from __future__ import annotations

from .bakefile import FORMAT_VERSION, read_bake, write_bake
from .mesh import Bake, baked_scene
from .pipeline import BakeConfig, bake_config, bake_scene
from ..render.lightmap_view import render_bake

__all__ = ["Bake", "BakeConfig", "FORMAT_VERSION", "bake_config", "bake_scene", "baked_scene", "read_bake",
           "render_bake", "write_bake"]
