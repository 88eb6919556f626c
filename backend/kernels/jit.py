"""The two decorators every compiled function uses: ``@kernel`` and ``@inlined``.

Both compile with Numba's ``njit``, cached on disk (Numba's cache, made on first use:
``_LazyCache``; the folder is chosen by ``kernels/cache.py``) and without reference counting
(``_nrt=False``: kernels never allocate; with counting, every array read from a table inside a
lane loop cost an atomic increment and decrement — 40 % of the shading time, 145 → 40 ns per
simple light sample). Extra Numba options pass through: ``@kernel(nogil=True)`` for lane loops
that render threads share, ``@kernel(error_model="numpy")`` where a division by zero must give
inf/NaN, not raise.

Both compile one version of a function per argument *types*: a constant passed between kernels
is not specialised on (``_one_version_per_type``).

``@inlined`` also makes LLVM inline the function into every caller (Numba's ``forceinline``,
LLVM's ``alwaysinline``). It is for functions that take a whole parameter table (materials,
textures, lights, layered stacks, the integrator's queues): a table is a tuple of arrays that a
non-inlined call passes as ~1 kB of flattened arguments (~50 ns a call).

Why not Numba's own ``inline="always"``: it inlines at the level of Numba's IR, so every call
site deep-copies and re-types the callee. For the shading kernel that was 30 % of the first
compilation (100 → 65 s on the warm-up scene; machine code as fast, measured in ABAB runs of
``benchmarks/core_throughput``).

Calls from other kernels compile the callee to LLVM IR only, without machine code or wrappers
(``link_only.py``): callers link IR, so only kernels called from Python need machine code.

Why ``@kernel`` says ``forceinline=False`` explicitly: Numba lets a function inherit
``forceinline`` from the function whose compilation first needs it, so without the explicit
flag every callee of an inlined function would be forced inline too, and whole call trees would
be re-optimised at each level (first compilation 65 → 125 s, measured).
"""
from __future__ import annotations

import types as _pytypes

from . import cache as _cache

_cache.configure()                  # before the first decorator: the keyed cache folder (kernels/cache.py)

import numba as _numba  # noqa: E402
from numba import njit  # noqa: E402
from numba.core import types as _nbtypes  # noqa: E402

from . import link_only as _link_only  # noqa: E402

_link_only.install(_numba)

_COMMON = {"_nrt": False}           # cached on disk too: _LazyCache below


class _LazyCache:
    """A dispatcher's on-disk cache (Numba's ``FunctionCache``), made when first used.

    ``cache=True`` makes one in the decorator, for every function at import: a locator search,
    the source file's stamp, the index name — 0.04-0.06 s for the ~300 functions of a warm start
    (measured), which calls about a dozen of them from Python (the rest are compiled into those).
    Numba uses the cache through a few methods (load, save, flush, cache_path); the first use
    puts the real object in its place, so the files and their names are Numba's own."""

    def __init__(self, dispatcher):
        self._dispatcher = dispatcher

    def __getattr__(self, name):
        from numba.core.caching import FunctionCache
        real = FunctionCache(self._dispatcher.py_func)
        self._dispatcher._cache = real
        return getattr(real, name)


#: Dispatchers being compiled by another process into the shared cache (kernels/cache.py):
#: id(dispatcher) → a function that waits for it. A call to one waits first, then loads it.
_COMPILED_ELSEWHERE: dict = {}


def compiled_elsewhere(dispatcher, wait) -> None:
    """Before this process compiles a call to ``dispatcher``, call ``wait()`` (another process
    is writing its machine code to the kernel cache, where the call then finds it)."""
    _COMPILED_ELSEWHERE[id(dispatcher)] = wait


def _call_template_without_literals(self, args, kws):
    wait = _COMPILED_ELSEWHERE.pop(id(self), None)
    if wait is not None:
        wait()
    args = tuple(_nbtypes.unliteral(a) for a in args)
    kws = {k: _nbtypes.unliteral(v) for k, v in kws.items()}
    with _link_only.for_callers():
        return type(self).get_call_template(self, args, kws)


def _one_version_per_type(dispatcher):
    """Calls from other kernels compile this function for the arguments' plain types.

    Numba types a constant argument of a call between compiled functions as a literal
    (``Literal[int](2)``) and compiles the callee once per constant: 74 of the ~270 compilations
    of the warm-up scene were such copies (e.g. the layered walk five times, the texture
    lookups once per parameter slot). Their machine code gained nothing measurable once LLVM
    inlines and folds the constants (Cornell box CPU +2 % ± 3 % over 6 ABAB pairs; layered
    eval/sample unchanged), while the first compilation took 70.5 → 57.8 s. Numba asks the
    callee's dispatcher for a call template with the argument types (``get_call_template``);
    this one passes them on without their literal values. No kernel needs a literal argument
    (a function that did would fail to type, in the tests)."""
    if hasattr(type(dispatcher), "get_call_template"):
        dispatcher.get_call_template = _pytypes.MethodType(_call_template_without_literals, dispatcher)
    return dispatcher


def _cached(dispatcher):
    dispatcher._cache = _LazyCache(dispatcher)
    return dispatcher


def _decorator(forceinline: bool, fn, options: dict):
    opts = {**_COMMON, **options, "forceinline": forceinline}
    if fn is not None:
        return _one_version_per_type(_cached(njit(**opts)(fn)))
    return lambda f: _one_version_per_type(_cached(njit(**opts)(f)))


def kernel(fn=None, **options):
    """A compiled function (``@kernel`` or ``@kernel(option=value, ...)``)."""
    return _decorator(False, fn, options)


def inlined(fn=None, **options):
    """A compiled function that LLVM inlines into every caller (see the module docstring)."""
    return _decorator(True, fn, options)
