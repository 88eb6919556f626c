"""Each family of kinds (lights, materials, phase functions) has one kind list and a declaration
of which dispatcher answers which kinds (``KINDS``, ``ANSWERS`` in backend/kernels/lights/dispatch.py,
backend/kernels/materials.py and backend/kernels/layered/phase.py); the dispatchers' branches (``kind == CODE`` comparisons, read from
the source) must match it, so a new kind code that lacks a branch in any dispatcher fails here."""
from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

from conftest import ROOT

FAMILIES = {"lights": "backend.kernels.lights.dispatch", "materials": "backend.kernels.materials",
            "phases": "backend.kernels.layered.phase"}
# A kind whose code constant is not its name in upper case.
CODE_NAMES = {"microflake": "fiber"}


def kind_names(module) -> dict[int, str]:
    """code → name (the phase family keeps name → code in ``KINDS`` and the inverse beside it)."""
    return getattr(module, "KIND_NAMES", None) or module.KINDS


def branches(module) -> dict[str, set[int]]:
    """{function: the kind codes it compares against} for the module's top-level functions."""
    path = Path(module.__file__)
    tree = ast.parse(path.read_text(encoding="utf-8"))
    codes = {name: value for name, value in vars(module).items()
             if name.isupper() and isinstance(value, int) and value in kind_names(module)
             and CODE_NAMES.get(kind_names(module)[value], kind_names(module)[value]).upper() == name}
    out = {}
    for fn in tree.body:
        if not isinstance(fn, ast.FunctionDef):
            continue
        seen = set()
        for node in ast.walk(fn):
            if isinstance(node, ast.Compare):
                for side in (node.left, *node.comparators):
                    if isinstance(side, ast.Name) and side.id in codes:
                        seen.add(codes[side.id])
        if seen:
            out[fn.name] = seen
    return out


@pytest.mark.parametrize("family", list(FAMILIES))
def test_every_dispatcher_branches_on_exactly_the_kinds_it_answers(family):
    module = importlib.import_module(FAMILIES[family])
    found = branches(module)
    assert set(found) == set(module.ANSWERS), (set(found) ^ set(module.ANSWERS))
    names = kind_names(module)
    for name, kinds in module.ANSWERS.items():
        missing = {names[k] for k in set(kinds) - found[name]}
        extra = {names[k] for k in found[name] - set(kinds)}
        assert not missing and not extra, f"{name}: no branch for {missing}, unexpected {extra}"


@pytest.mark.parametrize("family", list(FAMILIES))
def test_kind_codes_are_unique_and_every_kind_is_answered_somewhere(family):
    module = importlib.import_module(FAMILIES[family])
    kinds = kind_names(module)
    names = [n for n, v in vars(module).items() if n.isupper() and isinstance(v, int) and v in kinds
             and n.lower() in {CODE_NAMES.get(name, name).lower() for name in kinds.values()}]
    values = [getattr(module, n) for n in names]
    assert len(values) == len(set(values)) == len(kinds), dict(zip(names, values))
    answered = set().union(*map(set, module.ANSWERS.values()))
    assert answered == set(kinds), {kinds[k] for k in set(kinds) - answered}


def test_the_light_families_codes_live_in_their_kernel_modules():
    from backend.kernels.lights import dispatch
    for code, name in dispatch.KINDS.items():
        owner = {"collimated": "area", "constant": "environment"}.get(name, name)
        module = importlib.import_module(f"backend.kernels.lights.{owner}")
        assert getattr(module, name.upper()) == code, name
