"""Stage 1, the scene: the model (Scene, Material, Camera, lights), the
loaders (glTF 2.0, OBJ/MTL, PLY, built-in scenes by name), the kernels'
view of the surfaces and the lights' formulas, and the BVH."""
from .bvh import BVH, build_scene_bvh
from .camera import adjust_camera, auto_camera, camera_for
from .load import builtin_scenes, load_scene
from .prepared import Prepared, prepare
from .model import Camera, DynamicMesh, Material, PunctualLight, Scene, Sky, make_camera, sun
from .surfaces import Surfaces, pack

__all__ = ["BVH", "Camera", "Material", "Prepared", "PunctualLight", "Scene", "Sky", "Surfaces", "adjust_camera", "auto_camera",
           "build_scene_bvh", "builtin_scenes", "camera_for", "load_scene", "make_camera", "pack", "prepare", "sun"]
