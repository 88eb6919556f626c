"""Machine code only for the kernels that Python calls; their callees are compiled to LLVM IR.

Numba compiles every function it meets into a code library of its own, with a wrapper for
Python callers and one for C callers, and generates machine code for it (every callee linked
in), even when the function is only ever called by other compiled functions. Those callers link
the callee's *IR*: its machine code and its wrappers were made and never used, and in a call
tree of depth d the leaves were turned into machine code d times. Measured on the warm-up
compilation in one process (CPU): 110 s in all, of which machine code 22 s (5 s of it for the
shading kernel itself) and function passes 15.6 s (two thirds on the wrappers).

Here a function compiled because another compiled function calls it (Numba's typing asks its
dispatcher for a call template: ``jit._call_template_without_literals`` enters
``for_callers()``) is lowered without wrappers and optimised as before, and its library is
marked *IR only*: it is linked into its callers like any other, but never handed to the JIT
engine. A function called from Python or compiled explicitly (``dispatcher.compile(sig)``, as
the helper process of ``cache.py`` does) is compiled exactly as Numba does, and cached.
An IR-only version is not written to the on-disk cache (it has no machine code), is kept out
of the dispatcher's table of Python-callable versions, and is compiled again in full if Python
ever calls the function with those types.

Warm-up compilation, one process: 110-123 s → 72-80 s CPU; the first run of the demo (two
processes) 78–84 s → 50–52 s wall. The callers' machine code differs slightly (the callees' modules
are optimised without their wrappers in them): see docs/benchmarks.md for its speed.

Only for the pinned Numba (this relies on its internals, not its API); with any other version
``install`` does nothing and Numba compiles as it always does."""
from __future__ import annotations

import threading

from .cache import PINNED_NUMBA

_STATE = threading.local()


def _depth() -> int:
    return getattr(_STATE, "depth", 0)


class for_callers:
    """Compilations inside this context are for compiled callers only."""

    def __enter__(self):
        _STATE.depth = _depth() + 1

    def __exit__(self, *exc):
        _STATE.depth -= 1
        return False


def is_ir_only(compiled) -> bool:
    """A compile result (or a code library: the caches of ufuncs save those) made for callers."""
    return getattr(getattr(compiled, "library", compiled), "_lamina_ir_only", False)


def install(numba) -> bool:
    """Patch Numba's lowering pass, code libraries, CPU context, dispatchers and cache
    (idempotent). Returns whether it is in place."""
    from numba import _dynfunc
    from numba.core import caching, codegen, cpu, dispatcher, sigutils, typed_passes
    lib_cls = codegen.CPUCodeLibrary
    if getattr(lib_cls, "_lamina_link_only", False):
        return True
    if numba.__version__ != PINNED_NUMBA:
        return False

    # 1. Lowering: no wrappers for Python or C callers (they would call the machine code).
    lower = typed_passes.BaseNativeLowering.run_pass

    def run_pass(self, state):
        if _depth() > 0:
            state.flags.no_cpython_wrapper = True
            state.flags.no_cfunc_wrapper = True
        return lower(self, state)

    typed_passes.BaseNativeLowering.run_pass = run_pass

    # 2. The executable Numba makes after lowering: for callers, the library is finalised as IR
    #    and the "executable" is only the key under which callers' lowering finds the function
    #    (a function object at address 0, never called: see 3). Its environment object is not
    #    bound to the code; callers bind their own, as they do when loaded from the cache.
    get_executable = cpu.CPUContext.get_executable

    def get_executable_or_ir(self, library, fndesc, env):
        if _depth() == 0:
            return get_executable(self, library, fndesc, env)
        library._lamina_ir_only = True
        library._ensure_finalized()
        return _dynfunc.make_function(fndesc.lookup_module(), fndesc.qualname.split(".")[-1],
                                      "linked into compiled callers only", 0, env, (library,))

    cpu.CPUContext.get_executable = get_executable_or_ir

    finalize_module = lib_cls._finalize_final_module

    def _finalize_final_module(self):
        if not getattr(self, "_lamina_ir_only", False):
            return finalize_module(self)
        # Linked, optimised and verified IR is all callers need; Numba's last step hands the
        # module to the JIT engine for machine code, which waits until something asks for it.
        self._finalized = True

    def _emit(self):
        if getattr(self, "_lamina_ir_only", False) and not getattr(self, "_lamina_emitted", False):
            self._lamina_emitted = True
            finalize_module(self)

    def _emitting(name):
        original = getattr(lib_cls, name)

        def method(self, *args, **kwargs):
            _emit(self)
            return original(self, *args, **kwargs)
        method.__name__ = name
        setattr(lib_cls, name, method)

    for name in ("get_pointer_to_function", "get_asm_str", "get_disasm_cfg", "get_function_cfg"):
        if hasattr(lib_cls, name):
            _emitting(name)
    lib_cls._finalize_final_module = _finalize_final_module

    # 3. Dispatchers: an IR-only version is known to callers (overloads) but not callable from
    #    Python (not in the C table); a Python call with its types compiles it in full.
    add_overload = dispatcher.Dispatcher.add_overload

    def add_overload_or_ir(self, cres):
        if is_ir_only(cres):
            self.overloads[tuple(cres.signature.args)] = cres
            return None
        return add_overload(self, cres)

    dispatcher.Dispatcher.add_overload = add_overload_or_ir

    compile_ = dispatcher.Dispatcher.compile

    def compile_for_python(self, sig):
        if _depth() == 0:
            args = tuple(sigutils.normalize_signature(sig)[0])
            existing = self.overloads.get(args)
            if existing is not None and is_ir_only(existing):
                del self.overloads[args]
        return compile_(self, sig)

    dispatcher.Dispatcher.compile = compile_for_python

    # 4. The on-disk cache holds machine code: IR-only versions are not saved.
    save = caching.Cache.save_overload

    def save_overload(self, sig, data):
        if is_ir_only(data):
            return None
        return save(self, sig, data)

    caching.Cache.save_overload = save_overload
    lib_cls._lamina_link_only = True
    return True
