"""voxgi baker: scene -> voxels -> solution -> images/lightmaps.

Library surface (STYLE.md): `load_scene`, `voxelize`, `solve`, and the
renderers in `baker.pathtrace` / `baker.voxelview`.
"""
__version__ = "0.1.0"

from .errors import VoxgiError
from .scene import load_scene

__all__ = ["VoxgiError", "load_scene", "__version__"]
