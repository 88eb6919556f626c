"""Callees of compiled kernels are compiled to LLVM IR only (backend/kernels/link_only.py): no
machine code, no wrappers, nothing in the on-disk cache; a Python call with the same types
compiles the function in full. Run in a fresh process with a cache folder of its own, so that
the functions really compile (a warm cache would load the caller and never compile the callee)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

from conftest import ROOT

MODULE = textwrap.dedent('''
    from backend.kernels.jit import inlined, kernel


    @inlined
    def twice(x):
        return 2.0 * x


    @kernel
    def halve(x):
        return 0.5 * x


    @kernel
    def caller(x):
        return twice(x) + halve(x) + 1.0
''')

PROBE = textwrap.dedent('''
    import json, sys
    from pathlib import Path
    sys.path.insert(0, sys.argv[1])
    import numba
    from backend.kernels import cache, link_only
    import probe_funcs as m
    folder = cache.configure()
    out = {"installed": link_only.install(numba), "caller": m.caller(3.0)}
    out["ir_only"] = {f.__name__: [link_only.is_ir_only(c) for c in f.overloads.values()]
                      for f in (m.twice, m.halve, m.caller)}
    # The JIT engine holds machine code for the caller, none for the IR-only callee.
    def has_code(f):
        cres = next(iter(f.overloads.values()))
        return cres.library._codegen._engine.is_symbol_defined(cres.fndesc.mangled_name)
    out["has_code"] = [has_code(m.twice), has_code(m.caller)]
    out["indexed_before"] = sorted(p.name.split("-")[0] for p in folder.rglob("probe_funcs.*.nbi"))
    out["twice"], out["halve"] = m.twice(4.0), m.halve(4.0)      # Python calls: compiled in full
    out["ir_only_after"] = {f.__name__: [link_only.is_ir_only(c) for c in f.overloads.values()]
                            for f in (m.twice, m.halve)}
    out["indexed_after"] = sorted(p.name.split("-")[0] for p in folder.rglob("probe_funcs.*.nbi"))
    print(json.dumps(out))
''')


def test_callees_are_ir_only_until_python_calls_them(tmp_path):
    (tmp_path / "probe_funcs.py").write_text(MODULE)
    env = dict(os.environ, LAMINA_KERNEL_CACHE=str(tmp_path / "cache"), PYTHONPATH=str(ROOT))
    run = subprocess.run([sys.executable, "-c", PROBE, str(tmp_path)], capture_output=True, text=True,
                         env=env, cwd=ROOT, timeout=300)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["installed"]                                    # the pinned Numba (requirements.txt)
    assert out["caller"] == 3.0 * 2.0 + 1.5 + 1.0
    # Both callees (inlined or not) were compiled for the caller only; the caller in full.
    assert out["ir_only"] == {"twice": [True], "halve": [True], "caller": [False]}
    assert out["has_code"] == [False, True]
    assert out["indexed_before"] == ["probe_funcs.caller"]     # only the caller is cached
    # A Python call replaces the IR-only version by a full one, which is cached too.
    assert (out["twice"], out["halve"]) == (8.0, 2.0)
    assert out["ir_only_after"] == {"twice": [False], "halve": [False]}
    assert out["indexed_after"] == ["probe_funcs.caller", "probe_funcs.halve", "probe_funcs.twice"]
