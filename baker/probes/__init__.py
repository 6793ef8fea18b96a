"""Irradiance probes for moving objects: placed on a grid after the
solve, gathered from the voxel solution (gather.py), interpolated with
visibility (sample.py)."""
from .gather import ProbeGrid, bake_probes, grid_for
from .sample import interpolate

__all__ = ["ProbeGrid", "bake_probes", "grid_for", "interpolate"]
