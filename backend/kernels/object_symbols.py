"""The global symbols an ELF object file defines (the kernel cache's machine code on Linux).

Used to load a cached kernel without parsing its LLVM bitcode (kernels/cache.py): Numba parses
a cached library's bitcode only to list the symbols it defines, and keeps the module for
linking it into later compilations, which a warm start never does. ELF64 little-endian only
(Linux on x86-64 and AArch64); ``None`` for anything else, and the caller parses the bitcode."""
from __future__ import annotations

import struct

_SHT_SYMTAB = 2
_SHN_UNDEF = 0
_BINDINGS = (1, 2)          # STB_GLOBAL, STB_WEAK: what the JIT engine can look up by name


def defined_globals(obj: bytes) -> set[str] | None:
    """Names of the global and weak symbols defined in ``obj`` (None: not an ELF64 LE file, a
    malformed one, or one without a symbol table: the caller then parses the bitcode)."""
    if len(obj) < 64 or obj[:4] != b"\x7fELF" or obj[4] != 2 or obj[5] != 1:
        return None
    try:
        shoff, = struct.unpack_from("<Q", obj, 0x28)
        shentsize, shnum = struct.unpack_from("<HH", obj, 0x3A)
        names = None
        for k in range(shnum):
            sh_type, = struct.unpack_from("<I", obj, shoff + k * shentsize + 4)
            if sh_type != _SHT_SYMTAB:
                continue
            offset, size, link, _, _, entsize = struct.unpack_from("<QQIIQQ", obj, shoff + k * shentsize + 24)
            str_offset, = struct.unpack_from("<Q", obj, shoff + link * shentsize + 24)
            names = set() if names is None else names
            for s in range(offset, offset + size, entsize):
                st_name, st_info, _, st_shndx = struct.unpack_from("<IBBH", obj, s)
                if st_shndx != _SHN_UNDEF and (st_info >> 4) in _BINDINGS and st_name:
                    end = obj.index(b"\0", str_offset + st_name)
                    names.add(obj[str_offset + st_name:end].decode())
        return names
    except (struct.error, ValueError, UnicodeDecodeError):
        return None
