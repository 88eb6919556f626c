"""Compiled per-lane kernels (Numba).

Everything a path does between two embree calls runs here, one loop body per lane: hit-point
interpolation, shading frames, materials, textures, lights, MIS and Russian roulette. NumPy
orchestrates (work items, embree batches, compaction, film), loads scenes and writes images.

Where compiled code is cached is fixed *before* any kernel is defined: ``kernels/jit.py`` (the
decorators every kernel module imports) and ``kernels/ufuncs.py`` call ``cache.configure()``
first, which chooses a per-user cache folder keyed by the kernel sources, the Lamina, Numba and
Python versions, so a cache written by another version is never used. Never set Numba's cache
folder elsewhere. This package itself imports nothing compiled (nor Numba): constant modules
(``microfacet_codes``, ``layered/phase_layout``) and ``lazy`` serve parsers that need no kernels.

Conventions every kernel follows (measured reasons):
* Every compiled function is ``@kernel`` or ``@inlined`` (kernels/jit.py): cached, no reference
  counting (kernels never allocate; with counting, every array read from a table inside a lane
  loop cost an atomic increment and decrement: 40 % of the shading time, 145 → 40 ns per simple
  light sample).
* Functions that take a whole table (materials, textures, lights, the integrator's queues) are
  ``@inlined`` (LLVM inlines them): a table is a tuple of arrays passed by value, ~1 kB per
  non-inlined call (~50 ns). Per-kind functions below them take scalars, 3-tuples and single
  arrays.
* Lane loops over large batches release the GIL (``nogil=True``), so render threads share one
  process.
"""
