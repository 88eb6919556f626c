"""The split between the renderer and the Blender layer, checked on the source (AST, no imports):

* the backend never imports bpy or the add-on (it runs standalone and in a child process);
* the add-on uses no Python threads or process pools: Blender does not support Python threads
  (they crash it while the UI or an operator runs; the preset-thumbnail thread did, in CI), and
  rendering belongs to the backend's own process;
* the add-on imports nothing of the backend's rendering code (only preset files, errors and the
  LM-63 file reader, for the IES panel's peak intensity);
* compiled functions use the kernels/jit.py decorators (never Numba's njit directly)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from conftest import ROOT

FORBIDDEN_IN_ADDON = {"threading", "_thread", "multiprocessing", "concurrent", "asyncio"}
BACKEND_MODULES_THE_ADDON_MAY_USE = {"presets", "errors", "ies.lm63"}


def imports(path: Path):
    """(module, level, names) of every import; 'from . import x' gives ('', 1, ['x'])."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, 0, []
        elif isinstance(node, ast.ImportFrom):
            yield node.module or "", node.level, [a.name for a in node.names]


def sources(folder: str):
    files = sorted((ROOT / folder).rglob("*.py"))
    assert files, folder
    return files


@pytest.mark.parametrize("path", sources("backend"), ids=lambda p: str(p.relative_to(ROOT)))
def test_backend_never_imports_bpy_or_the_addon(path):
    depth = len(path.relative_to(ROOT / "backend").parts)       # relative levels that stay in backend/
    for module, level, _ in imports(path):
        top = module.split(".")[0]
        if level == 0:
            assert top not in ("bpy", "bmesh", "mathutils", "addon_utils", "addon"), (path, module)
        else:
            assert level <= depth, (path, module, level)         # never climbs out of backend/


@pytest.mark.parametrize("path", sources("addon"), ids=lambda p: str(p.relative_to(ROOT)))
def test_addon_uses_no_threads_and_no_backend_rendering_code(path):
    root_level = len(path.relative_to(ROOT / "addon").parts) + 1  # 'from <dots> import' at the repo root
    for module, level, names in imports(path):
        top = module.split(".")[0]
        if level == 0:
            assert top not in FORBIDDEN_IN_ADDON, (path, module)
            assert top != "backend", (path, module)
        elif level >= root_level:
            parts = module.split(".") if module else []
            if parts[:1] == ["backend"]:
                used = [".".join(parts[1:])] if len(parts) > 1 else names
                assert set(used) <= BACKEND_MODULES_THE_ADDON_MAY_USE, (path, module, names)


@pytest.mark.parametrize("path", sources("backend"), ids=lambda p: str(p.relative_to(ROOT)))
def test_compiled_functions_use_the_kernel_decorators(path):
    """Numba's njit only through kernels/jit.py (``@kernel`` / ``@inlined``): a bare njit would
    inherit ``forceinline`` from an inlined caller (whole call trees forced inline, a 2× slower
    first compilation) and could forget ``_nrt=False`` or the disk cache."""
    if path == ROOT / "backend" / "kernels" / "jit.py":
        return
    for module, level, names in imports(path):
        if level == 0 and module.split(".")[0] == "numba":
            assert "njit" not in names and "jit" not in names, (path, module, names)
