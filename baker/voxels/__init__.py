"""Stage 2, the voxels: sparse surface voxelization (exact clipping of the
triangles to cells, sheets, surfaces crossing a cell) and the lookups from
a surface point to its voxel."""
from .voxelize import Grid, Voxels, estimate, grid_for, resolution_for, surface_resolution, voxelize

__all__ = ["Grid", "Voxels", "estimate", "grid_for", "resolution_for", "surface_resolution", "voxelize"]
