"""The import structure of backend/ and addon/, read from the source (every import statement,
module-level or inside a function; nothing is imported or run).

* No import circles, except the one recursion that the material schema itself has: a material
  may name a preset, a preset holds a material, a Mix Shader holds materials
  (scene/loader.py ↔ presets.py, scene/loader.py ↔ materials/mix.py).
* The compiled kernels (backend/kernels/) import nothing of the backend above them: only the
  version and the error classes. What builds their tables from scene objects lives with those
  objects (backend/layered/stack_table.py, the lights' ``pack``), and what renders a scene to
  compile them lives above the integrator (backend/warmup.py).
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("backend", "addon")
# The one circle allowed (module paths relative to the repository).
MATERIAL_RECURSION = {"backend/scene/loader.py", "backend/presets.py", "backend/materials/mix.py"}
KERNELS_MAY_IMPORT = {"backend/__init__.py", "backend/errors.py"}


def _module_file(parts: list[str]) -> str | None:
    """The file of module ``parts`` (a package's __init__.py), or None outside the tree."""
    base = ROOT.joinpath(*parts)
    if base.with_suffix(".py").is_file():
        return str(base.with_suffix(".py").relative_to(ROOT))
    if (base / "__init__.py").is_file():
        return str((base / "__init__.py").relative_to(ROOT))
    return None


def _imports(path: Path) -> set[str]:
    """The files of this tree that ``path`` imports."""
    rel = path.relative_to(ROOT)
    package = list(rel.parent.parts)
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        targets = []
        if isinstance(node, ast.Import):
            targets = [alias.name.split(".") for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)]
                mod = base + (node.module.split(".") if node.module else [])
            else:
                mod = node.module.split(".") if node.module else []
            for alias in node.names:
                # "from pkg import name": a submodule of pkg, or a definition in pkg itself
                sub = mod + [alias.name]
                targets.append(sub if _module_file(sub) is not None else mod)
        for parts in targets:
            if not parts or parts[0] not in PACKAGES:
                continue
            f = _module_file(parts)
            if f is not None and f != str(rel):
                out.add(f)
    return out


def _graph() -> dict[str, set[str]]:
    files = [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py") if "__pycache__" not in p.parts]
    return {str(p.relative_to(ROOT)): _imports(p) for p in files}


def _circles(graph: dict[str, set[str]]) -> list[set[str]]:
    """Strongly connected components with more than one file (Tarjan, iterative)."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if w not in graph:
                    continue
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    advanced = True
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = set()
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.add(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(comp)
    return out


def test_the_reader_sees_imports():
    """The graph is read right: known arrows of both kinds (module level, inside a function)."""
    graph = _graph()
    assert "backend/kernels/jit.py" in graph["backend/kernels/integrator.py"]
    assert "backend/presets.py" in graph["backend/scene/loader.py"]          # inside parse_material
    assert "backend/warmup.py" in graph["backend/render.py"]                  # inside Renderer.run
    assert "addon/launch.py" in graph["addon/engine/viewport.py"]


def test_no_import_circles_but_the_material_recursion():
    circles = _circles(_graph())
    assert [c for c in circles if c != MATERIAL_RECURSION] == [], circles


def test_kernels_import_nothing_above_them():
    graph = _graph()
    up = {(f, t) for f, ts in graph.items() if f.startswith("backend/kernels/")
          for t in ts if not t.startswith("backend/kernels/") and t not in KERNELS_MAY_IMPORT}
    assert up == set(), sorted(up)
