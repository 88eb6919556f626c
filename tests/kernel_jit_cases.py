"""Tiny compiled functions for tests/test_kernels_core.py's checks of kernels/jit.py (module level:
Numba caches only module-level functions)."""
from backend.kernels.jit import inlined, kernel


@kernel
def scale(x, k):
    return x * k


@inlined
def scale_inlined(x, k):
    return scale(x, k)


@kernel
def two_constants(x):
    return scale(x, 2) + scale_inlined(x, 3)
