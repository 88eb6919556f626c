"""The split between the renderer and the Blender layer, checked on the source (AST, no imports):

* the backend never imports bpy or the add-on (it runs standalone and in a child process);
* the add-on uses no Python threads or process pools: Blender does not support Python threads
  (they crash it while the UI or an operator runs; the preset-thumbnail thread did, in CI), and
  rendering belongs to the backend's own process;
* the add-on imports nothing of the backend's rendering code (only preset files, errors and the
  LM-63 file reader, for the IES panel's peak intensity);
* compiled functions use the kernels/jit.py decorators (never Numba's njit directly);
* comments and docstrings cite only files that are in the repository (docs/architecture.md is the
  map; a design document or digest outside it cannot be read by the next contributor)."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from conftest import ROOT

FORBIDDEN_IN_ADDON = {"threading", "_thread", "multiprocessing", "concurrent", "asyncio"}
BACKEND_MODULES_THE_ADDON_MAY_USE = {"presets", "errors", "ies.lm63", "render_settings", "layered.phase_schema"}


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


# A path-like token in a comment or docstring: folders, then a file with a known suffix.
CITED_PATH = re.compile(r"(?<![\w/.])((?:[\w-]+/)+[\w-]+\.(?:py|md|json|txt|toml))\b")
OUTSIDE = re.compile(r"DESIGN\.md|DESIGN §|digest §|guo2018-digest|\.\./shared/")
# Tokens that name no file of the repository on purpose (an example path; the installed
# packages an extension test looks for).
NOT_FILES = {"x/scene/scene.json", "embreex/__init__.py", "numba/__init__.py", "llvmlite/__init__.py"}


@pytest.mark.parametrize("folder", ["backend", "addon", "tests", "benchmarks", "tools"])
def test_comments_cite_only_files_in_the_repository(folder):
    missing = []
    for path in sources(folder):
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            where = f"{path.relative_to(ROOT)}:{n}"
            if OUTSIDE.search(line) and path.name != "test_architecture.py":
                missing.append(f"{where}: cites a document outside the repository")
            for m in CITED_PATH.finditer(line):
                token = m.group(1)
                if token in NOT_FILES:
                    continue
                # as written from the root, from a top folder, or from the citing file's folder
                bases = (ROOT, ROOT / "backend", ROOT / "addon", ROOT / "tests", ROOT / "docs", path.parent)
                if not any((base / token).exists() for base in bases):
                    missing.append(f"{where}: {token}")
    assert not missing, "\n".join(missing)
