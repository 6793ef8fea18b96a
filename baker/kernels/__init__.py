"""numba kernels: flat arrays in and out, no I/O, no classes (STYLE.md)."""
