"""Command-line argument types with their valid ranges, and a parser whose
own rejections are one line in our format (`error: ...`, exit 2).

Every numeric flag states its range here, in its type, so that a value
outside it (10^30 photons, a cell size of 1e-300, NaN, inf) is refused
while the arguments are parsed, before any work.
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np

SEED_MAX = 2 ** 31 - 1


class OneLineParser(argparse.ArgumentParser):
    """argparse's rejections as one line, `error: <problem> (see --help)`,
    exit status 2, in place of the usage block."""

    def error(self, message):
        print(f"error: {message} (see '{self.prog} --help')", file=sys.stderr)
        raise SystemExit(2)


def integer(lo: int, hi: int):
    """An argparse type: an integer in lo..hi."""
    def parse(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer in {lo}..{hi:,}, got {text!r}") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"must lie in {lo}..{hi:,}, got {text}")
        return v
    parse.__name__ = "integer"
    return parse


def number(lo: float, hi: float, lo_open=False):
    """An argparse type: a finite number in lo..hi (lo excluded when
    lo_open)."""
    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not math.isfinite(v) or v > hi or v < lo or (lo_open and v == lo):
            span = f"above {lo:g} and at most {hi:g}" if lo_open else f"in {lo:g}..{hi:g}"
            raise argparse.ArgumentTypeError(f"must be a finite number {span}, got {text}")
        return v
    parse.__name__ = "number"
    return parse


def triple(text, what="X,Y,Z", bound=1e18):
    """Three finite numbers of magnitude at most `bound`, as X,Y,Z."""
    try:
        v = [float(t) for t in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if len(v) != 3 or not np.all(np.isfinite(v)) or max(abs(x) for x in v) > bound:
        raise argparse.ArgumentTypeError(f"expected {what} (three finite numbers within +-{bound:g}), got {text!r}")
    return np.array(v)


RADIANCE_MAX = 1e9  # W m^-2 sr^-1 (or W/m^2 for the sun): far above the sun's disc, far below float32's range


def colour(text):
    """R,G,B radiance, each in 0..RADIANCE_MAX."""
    v = triple(text, "R,G,B", RADIANCE_MAX)
    if (v < 0).any():
        raise argparse.ArgumentTypeError(f"radiance must not be negative, got {text!r}")
    return v


def sun(text):
    """AZIMUTH,ELEVATION,IRRADIANCE of a sun."""
    az, el, e = triple(text, "AZIMUTH,ELEVATION,IRRADIANCE", 1e9)
    if not -90 <= el <= 90 or not 0 <= e <= RADIANCE_MAX or not -360 <= az <= 360:
        raise argparse.ArgumentTypeError(f"azimuth must lie in -360..360, elevation in -90..90 and irradiance in "
                                         f"0..{RADIANCE_MAX:g}, got {text!r}")
    return az, el, e


# the ranges of the flags both commands share
THREADS = integer(0, 4096)
EXPOSURE = number(-64, 64)
IMAGE_SIDE = integer(1, 16384)
SEED = integer(0, SEED_MAX)
