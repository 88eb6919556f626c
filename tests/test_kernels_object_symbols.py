"""kernels/object_symbols.py: the global symbols of a kernel's ELF machine code are the names
LLVM's own reading of the same module's bitcode gives for its non-private definitions."""
from __future__ import annotations

import sys

import pickle

import pytest
from llvmlite import binding as ll

from backend.kernels import cache
from backend.kernels.object_symbols import defined_globals
from backend.warmup import ensure_compiled


def _cached_libraries(folder):
    """(file name, object code, bitcode) of every kernel in the on-disk cache."""
    def find(o):
        if isinstance(o, tuple):
            if len(o) == 3 and o[1] == "object":
                return o[2]
            for x in o:
                found = find(x)
                if found:
                    return found
        return None
    for path in sorted(folder.rglob("*.nbc")):
        found = find(pickle.loads(path.read_bytes()))
        if found:
            yield path.name, found[0], found[1]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="ELF machine code on Linux only")
def test_elf_globals_are_the_bitcode_definitions_that_are_not_private():
    ensure_compiled()                      # the session's kernel cache (compiled if cold)
    checked = entry_points = 0
    for name, obj, bitcode in _cached_libraries(cache.configure()):
        module = ll.parse_bitcode(bitcode)
        expected = {v.name for vs in (module.functions, module.global_variables) for v in vs
                    if not v.is_declaration and v.linkage not in (ll.Linkage.private, ll.Linkage.internal)}
        got = defined_globals(obj)
        assert got == expected and got, name
        entry_points += any(n.startswith("_ZN7cpython") for n in got)   # a Python entry point
        checked += 1
    assert entry_points >= 10                    # the kernels the renderer calls from Python


def test_anything_else_is_not_read():
    assert defined_globals(b"") is None
    assert defined_globals(b"\xcf\xfa\xed\xfe" + bytes(60)) is None          # Mach-O
    assert defined_globals(b"\x7fELF\x01\x01" + bytes(58)) is None           # 32-bit ELF
    header = b"\x7fELF\x02\x01" + bytes(34) + (10 ** 6).to_bytes(8, "little") + bytes(10)
    assert defined_globals(header + (64).to_bytes(2, "little") + (0).to_bytes(4, "little")) is None  # no sections
    assert defined_globals(header + (64).to_bytes(2, "little") + (3).to_bytes(4, "little")) is None  # cut short
