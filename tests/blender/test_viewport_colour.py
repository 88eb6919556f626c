"""A stack material shows its colour in Cycles/EEVEE through the add-on's Principled approximation,
and the user's own output comes back when the stack is turned off (addon/ops/viewport_colour.py)."""
from __future__ import annotations

import pytest

from bpy_harness import requires_bpy, result_of, run_cases

pytestmark = [pytest.mark.blender, requires_bpy]


def test_a_preset_gets_its_colour_and_gives_the_output_back(tmp_path):
    r = result_of(run_cases("viewport_colour_cases", ["approximation"], tmp=tmp_path), "approximation")
    assert r["before"] == r["users_output"]                # nothing runs by itself under -b
    assert r["ok"] and r["again"] and r["active"] == "Lamina Viewport Output"
    red, green, blue = r["colour"]
    assert red > 2 * green and red > 2 * blue and red > 0.1, r["colour"]    # car paint red is red
    assert r["metallic"] == 1.0                            # its bottom interface is a conductor (the flakes)
    assert r["after_off"] == r["users_output"]
