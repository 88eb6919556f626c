"""Odd-stack warnings (addon/stack_check.py, no bpy) and the add-on's metal list vs the backend's."""
from __future__ import annotations

import importlib.util

from conftest import ROOT


def load(name, path):
    spec = importlib.util.spec_from_file_location(name, ROOT / path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


check = load("stack_check", "addon/stack_check.py").check_material
constants = load("addon_constants", "addon/constants.py")

DIEL = {"type": "dielectric", "ior": 1.5}
COPPER = {"type": "conductor", "metal": "Cu"}
CLEAR = {"thickness": 1.0, "sigma_t": 0.0}


def levels(findings, word):
    return [level for level, message in findings if word in message]


def test_well_formed_stack_has_no_warnings():
    assert check({"type": "layered", "interfaces": [DIEL, COPPER], "media": [CLEAR]}) == []


def test_conductor_not_last_is_flagged():
    findings = check({"type": "layered", "interfaces": [COPPER, DIEL, {"type": "diffuse"}],
                      "media": [CLEAR, CLEAR]})
    assert levels(findings, "opaque") == ["WARNING"]
    assert "2 interface(s) below it" in findings[0][1]


def test_transmissive_bottom_index_matched_and_thick_media():
    findings = check({"type": "layered",
                      "interfaces": [DIEL, {"type": "dielectric", "ior": 1.5}, {"type": "null"}],
                      "media": [{"thickness": 10.0, "sigma_t": 5.0}, CLEAR]})
    assert levels(findings, "transmits") == ["INFO"]
    assert levels(findings, "same IOR") == ["INFO"]
    assert levels(findings, "optically very thick") == ["WARNING"]


def test_textured_density_uses_its_scale():
    findings = check({"type": "layered", "interfaces": [DIEL, COPPER],
                      "media": [{"thickness": 2.0, "sigma_t": {"texture": "d.png", "scale": 20.0}}]})
    assert levels(findings, "optically very thick") == ["WARNING"]


def test_single_interfaces_are_not_checked():
    assert check(COPPER) == []


def test_metal_names_match_the_backend():
    from backend.materials.metals import METALS
    assert [symbol for symbol, _ in constants.METALS] == sorted(METALS)
