"""The stack's Principled approximation for other engines (addon/viewport_colour.py, no bpy): the
mapping from a stack and its measured albedo to Principled inputs. The nodes themselves and the
albedo they carry are checked on the showcase .blend (tests/blender/test_showcase_blend.py)."""
from __future__ import annotations

import importlib.util
import math

import pytest

from conftest import ROOT

spec = importlib.util.spec_from_file_location("viewport_colour", ROOT / "addon" / "viewport_colour.py")
vc = importlib.util.module_from_spec(spec)
spec.loader.exec_module(vc)


def test_textures_become_their_constants():
    doc = {"type": "layered", "interfaces": [
        {"type": "dielectric", "ior": 1.5, "roughness": {"texture": "r.png", "scale": 0.2}},
        {"type": "diffuse", "color": {"texture": "wood.png"}}],
        "media": [{"sigma_t": {"texture": "d.exr", "scale": [0.1, 0.2, 0.3]}, "albedo": 0.9}]}
    out = vc.constant_doc(doc)
    assert out["interfaces"][0]["roughness"] == 0.2
    assert out["interfaces"][1]["color"] == vc.GREY
    assert out["media"][0]["sigma_t"] == [0.1, 0.2, 0.3] and out["media"][0]["albedo"] == 0.9
    assert doc["interfaces"][1]["color"] == {"texture": "wood.png"}          # the input is not changed


def test_a_coated_metal_is_metallic_with_the_coats_roughness():
    doc = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.04},
                                             {"type": "conductor", "metal": "Au", "roughness": 0.3}]}
    p = vc.principled_inputs(doc, {"R": [0.8, 0.6, 0.3], "T": [0, 0, 0]})
    assert p == {"base_color": (0.8, 0.6, 0.3), "metallic": 1.0, "roughness": pytest.approx(0.2),
                 "transmission": 0.0}


def test_plastic_and_diffuse_and_glass():
    plastic = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.25},
                                                 {"type": "diffuse", "color": [0.7, 0.1, 0.1]}]}
    p = vc.principled_inputs(plastic, {"R": [0.62, 0.12, 0.11], "T": [0, 0, 0]})
    assert p["metallic"] == 0.0 and p["roughness"] == pytest.approx(0.5) and p["transmission"] == 0.0
    assert p["base_color"] == (0.62, 0.12, 0.11)
    lambert = vc.principled_inputs({"type": "diffuse", "color": 0.5}, {"R": [0.5, 0.5, 0.5], "T": [0, 0, 0]})
    assert lambert["roughness"] == 1.0 and lambert["metallic"] == 0.0
    glass = vc.principled_inputs({"type": "dielectric", "ior": 1.5, "roughness": 0.0},
                                 {"R": [0.08, 0.08, 0.08], "T": [0.9, 0.6, 0.2]})
    assert glass["transmission"] == pytest.approx(0.5667 / (0.08 + 0.5667), abs=1e-3)
    assert glass["base_color"] == pytest.approx((0.98, 0.68, 0.28))
    # Out-of-range measurements (Monte Carlo noise) are clipped to what a colour can hold.
    odd = vc.principled_inputs(plastic, {"R": [1.02, -0.001, 0.5], "T": [0, 0, 0]})
    assert odd["base_color"] == (1.0, 0.0, 0.5)
    assert math.isclose(vc.principled_inputs(plastic, {"R": [0.2] * 3})["roughness"], 0.5)
