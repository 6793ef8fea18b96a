"""A scene made ready for the kernels once: the Scene, its BVH and its
Surfaces (the kernels' view of its materials, lights and sky). Every
pipeline (solve, the bake, a frame) takes a Prepared or a Scene, and
prepares a Scene itself."""
from __future__ import annotations

from dataclasses import dataclass

from .bvh import BVH, build_scene_bvh
from .model import Scene
from .surfaces import Surfaces, pack


@dataclass(frozen=True)
class Prepared:
    scene: Scene
    bvh: BVH
    surfaces: Surfaces


def prepare(scene, bvh=None, surfaces=None) -> Prepared:
    """`scene` (a Scene, or a Prepared returned as it is) with its BVH and
    Surfaces, built unless given."""
    if isinstance(scene, Prepared):
        return scene
    return Prepared(scene, bvh or build_scene_bvh(scene), surfaces or pack(scene))
