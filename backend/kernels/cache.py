"""Where compiled kernels are cached, how they are loaded from there, and whether the cache is warm
(``is_warm``; the first-run compilation itself is backend/warmup.py's).

Numba's ``cache=True`` writes machine code next to a per-function index. Its own staleness check
looks only at the modification time of the file that defines a function, not at the files of the
functions it calls, so editing a shared helper would leave stale callers in the cache. Lamina
therefore keys the whole cache folder by a hash of every source file of ``backend/kernels/`` (and
of any other file under ``backend/`` that calls Numba), plus the Lamina, Numba, llvmlite and
Python versions: any change gives a new, empty folder (another version's cache is ignored, not
trusted).

Folder (first match):
  1. ``$LAMINA_KERNEL_CACHE`` (the Blender add-on sets it to the extension's user folder);
  2. the platform's user cache directory: ``$XDG_CACHE_HOME`` or ``~/.cache`` (Linux),
     ``~/Library/Caches`` (macOS), ``%LOCALAPPDATA%`` (Windows), + ``/lamina/kernels``.
Never the install folder (it may be read-only, and it is shared between users).
"""
from __future__ import annotations

import hashlib
import os
import sys
import time
from pathlib import Path

BACKEND = Path(__file__).resolve().parent.parent
#: The Numba whose internals the cache loader (here) and link_only.py patch; any other version
#: loads and compiles as Numba itself does.
PINNED_NUMBA = "0.68.1"
_STATE = {"dir": None, "key": None}


def user_cache_root() -> Path:
    env = os.environ.get("LAMINA_KERNEL_CACHE")
    if env:
        return Path(env)
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "lamina" / "kernels"


def source_key() -> str:
    """Hash of the kernel sources and the toolchain versions (16 hex digits)."""
    import llvmlite
    import numba

    from .. import __version__
    digest = hashlib.sha256()
    digest.update(f"{__version__}|{numba.__version__}|{llvmlite.__version__}|{sys.version}".encode())
    kernels = BACKEND / "kernels"
    for path in sorted(BACKEND.rglob("*.py")):
        text = path.read_bytes()
        # Files that may define compiled code: the kernels package (its decorators are
        # kernels/jit.py's), and anything else that calls Numba directly.
        if kernels in path.parents or b"njit" in text or b"vectorize" in text:
            digest.update(str(path.relative_to(BACKEND)).encode())
            digest.update(text)
    return digest.hexdigest()[:16]


def _import_numba():
    """numba, or one clear error naming the fix (never a traceback, never a black image)."""
    try:
        import llvmlite  # noqa: F401
        import numba
    except Exception as exc:  # noqa: BLE001 - ImportError, or a broken binary (OSError)
        from ..errors import LaminaError
        raise LaminaError(
            f"the compiled render kernels need Numba, which could not be imported into "
            f"{sys.executable} ({type(exc).__name__}: {exc}). Fix: in Blender, install the Lamina "
            f"extension zip built for your platform (it bundles numba and llvmlite); elsewhere, "
            f"install the pinned versions with "
            f"`python -m pip install numba=={PINNED_NUMBA} llvmlite==0.50.0` "
            f"(see requirements.txt)") from None
    return numba


def configure() -> Path:
    """Point Numba's cache at the keyed folder (idempotent). Returns the folder."""
    if _STATE["dir"] is not None:
        return _STATE["dir"]
    numba = _import_numba()
    key = source_key()
    folder = user_cache_root() / key
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / ".writable"
        probe.touch()
    except OSError:
        # A read-only home (some farm nodes): compile into a private temporary folder instead.
        import tempfile
        folder = Path(tempfile.gettempdir()) / f"lamina-kernels-{os.getuid() if hasattr(os, 'getuid') else 0}" / key
        folder.mkdir(parents=True, exist_ok=True)
    numba.config.CACHE_DIR = str(folder)
    _lean_cache_loads(numba)
    _STATE["dir"], _STATE["key"] = folder, key
    return folder


def _lean_cache_loads(numba) -> None:
    """Load cached kernels without Numba's compiler set-up.

    Before every cache load Numba "refreshes" its target context: it imports and registers every
    lowering and typing implementation it has (its whole NumPy, typed-container, random, ...
    support, and SciPy's BLAS bindings to see whether ``np.dot`` can compile) — what *compiling*
    needs. Rebuilding cached machine code needs only the runtime (NRT) initialised. Measured on the
    64² material preview (warm caches): the refresh was 0.17–0.34 s of its ~1 s. Numba still
    refreshes when it compiles (its compiler refreshes both contexts first, and lowering refreshes
    on a missing implementation), so a cache miss compiles as before. Only for the pinned Numba
    (the internals this replaces are not API); any other version keeps Numba's own loader."""
    from numba.core import caching
    load = caching.Cache.load_overload
    if getattr(load, "lamina_lean", False) or numba.__version__ != PINNED_NUMBA \
            or not hasattr(caching.Cache, "_guard_against_spurious_io_errors") \
            or not hasattr(caching.Cache, "_load_overload"):
        return
    from numba.core.runtime import rtsys
    # Of the modules the refresh imports, this one also registers machine-code symbols (the
    # hash secret read by compiled ``hash()``); a kernel referring to an unregistered symbol
    # would abort the process when loaded, so register it here (≈ 3 ms). The NRT's symbols come
    # with rtsys.initialize, the C math and helper functions with the target context itself.
    import numba.cpython.hashing  # noqa: F401

    def load_overload(self, sig, target_context):
        rtsys.initialize(target_context)       # idempotent; the part of refresh() loading needs
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)

    load_overload.lamina_lean = True
    _STATE["numba_load_overload"] = load          # Numba's own (the tests compare the two)
    caching.Cache.load_overload = load_overload
    _bitcode_on_demand()


def _bitcode_on_demand() -> None:
    """Load a cached kernel's machine code without parsing its LLVM bitcode.

    A cached library holds machine code and the bitcode of the same module. Numba parses the
    bitcode on every load, to list the symbols the module defines and to keep the module for
    linking into later compilations; a render only runs the machine code. Parsing was 78 ms for
    the shading kernel (913 kB) and about 120 ms for the kernels of a warm start (measured). Here
    the defined symbols come from the machine code's ELF symbol table (kernels/object_symbols.py:
    the global ones, which are those the JIT engine can look up; the bitcode adds only private
    constants), and the bitcode is parsed when a compilation first links the library. Not an
    ELF object (macOS, Windows): Numba's own load."""
    from numba.core import codegen

    from .object_symbols import defined_globals
    lib_cls = codegen.CPUCodeLibrary
    unserialize = lib_cls._unserialize.__func__
    for_linking = lib_cls._get_module_for_linking

    def _unserialize(cls, codegen_, state):
        name, kind, data = state
        symbols = defined_globals(data[0]) if kind == "object" else None
        if symbols is None:
            return unserialize(cls, codegen_, state)
        self = codegen_.create_library(name)
        self.enable_object_caching()
        self._set_compiled_object(data[0])
        self._lamina_bitcode = data[1]
        self._finalize_final_module()
        codegen_._engine._defined_symbols |= symbols
        return self

    def _get_module_for_linking(self):
        bitcode = getattr(self, "_lamina_bitcode", None)
        if bitcode is not None:
            from llvmlite import binding as ll
            self._lamina_bitcode = None
            self._shared_module = ll.parse_bitcode(bitcode)
            self._codegen._engine._load_defined_symbols(self._shared_module)
        return for_linking(self)

    # Numba's own (the tests compare the two)
    _STATE["numba_library_load"] = (lib_cls._unserialize, for_linking)
    lib_cls._unserialize = classmethod(_unserialize)
    lib_cls._get_module_for_linking = _get_module_for_linking


def marker() -> Path:
    return configure() / "warm"


def is_warm() -> bool:
    return marker().exists()
