"""Counter-based random numbers: a hash of (seed, index, dimension).

No state is carried between samples, so which thread draws a number does not
change it: images and photon sets are identical for any thread count.
"""
import numpy as np
from numba import njit

_C1 = np.uint64(0x9E3779B97F4A7C15)
_C2 = np.uint64(0xBF58476D1CE4E5B9)
_C3 = np.uint64(0x94D049BB133111EB)
_INV53 = 1.0 / 9007199254740992.0


@njit(cache=True, inline="always")
def mix64(x):
    """splitmix64 finaliser (Steele, Lea & Flood 2014): a bijection of uint64."""
    x = (x ^ (x >> np.uint64(30))) * _C2
    x = (x ^ (x >> np.uint64(27))) * _C3
    return x ^ (x >> np.uint64(31))


@njit(cache=True, inline="always")
def keyed(seed, index):
    """The 64-bit hash of (seed, index) that every random stream starts
    from (rand01, the Sobol scrambles, the light tree's representatives,
    the texels' inside-test directions)."""
    return mix64(np.uint64(seed) * _C1 + np.uint64(index))


def seed_unit(seed) -> float:
    """A number in [0, 1) from the seed alone, in plain Python (the light
    tree's root representative, drawn outside the kernels)."""
    return ((int(seed) * 0x9E3779B97F4A7C15) % (1 << 64) >> 11) / float(1 << 53)


@njit(cache=True, inline="always")
def rand01(seed, index, dim):
    """Uniform double in [0, 1) for (seed, index, dim); all three int-like."""
    h = keyed(seed, index)
    h = mix64(h ^ (np.uint64(dim) * _C2 + _C1))
    return float(h >> np.uint64(11)) * _INV53


# The random streams: which (index, dimension) ranges of rand01 each use
# draws from, in one table so that two uses never share numbers by accident.
# (Changing a value changes every result that depends on it.)
STREAM_PHOTON_ROTATION = 0x5EED      # index; dims 0..7: the photons' Cranley-Patterson rotation (photons.py)
STREAM_PHOTON_GLASS = 0x61A55         # seed (mixed with the photons' rotation); index the photon, dim its pane
STREAM_LINE_OFFSETS = 7              # dims 7, 8: a family's line offsets mu, mu' ...
LINE_OFFSET_BOUNCE_STRIDE = 1_000_003  # ... at index bounce * stride + family (propagate.py)
STREAM_ROULETTE = 0xD1CE              # the path tracer's Russian roulette: seed mixed with pixel + this; index
                                     # the sample, dim the depth (its other numbers: kernels/sobol.py groups);
ROULETTE_GLASS_DIM = 1 << 20         # dims from here + depth: whether the path goes through thin glass
STREAM_AUDIT_FAMILIES = 77           # index; dim i: the audit's i-th family (audit.py)
STREAM_AUDIT_VOXELS = 1000           # index 1000 + family; dim i: the audit's i-th voxel of that family
STREAM_PROBE_EMITTERS = 0x9B0BE      # seed mixed with this; index the probe, dims 0..2: its emitter samples' rotation
