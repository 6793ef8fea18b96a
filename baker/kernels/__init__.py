"""Shared numba primitives (no stage logic): random numbers, sampling, BVH
build and traversal, prefetch. Flat arrays in and out, no I/O, no classes."""
