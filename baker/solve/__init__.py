"""Stage 3, the solution: directions, photons (the first bounce), linear
propagation over the voxels (the rest), the cache method that chains the
bounces, and the visibility audit."""
from .cache_method import Solution, solve
from .directions import DirectionSet, direction_set
from .propagate import LineSweeper

__all__ = ["DirectionSet", "LineSweeper", "Solution", "direction_set", "solve"]
