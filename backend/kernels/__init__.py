"""Compiled per-lane kernels (Numba).

Everything a path does between two embree calls runs here, one loop body per lane: hit-point
interpolation, shading frames, materials, textures, lights, MIS and Russian roulette. NumPy
orchestrates (work items, embree batches, compaction, film), loads scenes and writes images.

Importing this package fixes where compiled code is cached *before* any kernel module is
imported: ``backend.kernels.cache`` chooses a per-user cache folder keyed by the kernel sources,
the Lamina, Numba and Python versions, so a cache written by another version is never used.
Kernel modules must therefore be imported through this package (``from ..kernels import ...``),
never by setting Numba's cache folder elsewhere.
"""
from . import cache as _cache

_cache.configure()
