"""Compiled-kernel infrastructure: numba kernels, their ahead-of-time build, cache and threads."""
