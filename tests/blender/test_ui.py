"""Add-on registration, layer-stack operators, panels (draw calls recorded) and presets."""
from __future__ import annotations

import pytest

from bpy_harness import requires_bpy, result_of, run_cases

pytestmark = [pytest.mark.blender, requires_bpy]

CASES = ["registration", "compositor_sockets", "operators", "stack_panel", "light_and_render_panels", "presets"]


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    return run_cases("ui_cases", CASES, tmp=tmp_path_factory.mktemp("ui"))


def props_drawn(calls):
    return {c[1] for c in calls if c[0] == "prop"}


def test_registration_and_builtin_panels(results):
    r = result_of(results, "registration")
    assert "LaminaRenderEngine" in r["engines"] and "LAMINA" in r["engine_items"]
    compat = r["compat"]
    for name in ("DATA_PT_lens", "DATA_PT_camera_dof", "RENDER_PT_format", "RENDER_PT_output",
                 "RENDER_PT_color_management", "MATERIAL_PT_preview", "EEVEE_MATERIAL_PT_context_material"):
        assert compat[name], name
    assert not compat["DATA_PT_light"] and not compat["RENDER_PT_freestyle"]
    assert not any(r["after_disable"].values()), "unregister must remove LAMINA from built-in panels"
    assert not r["prop_after_disable"] and r["reenabled"]


def test_denoise_passes_reach_the_compositor(results):
    outputs = result_of(results, "compositor_sockets")
    assert {"Image", "Denoising Albedo", "Denoising Normal"} <= set(outputs)


def test_stack_operators(results):
    r = result_of(results, "operators")
    k = r["kinds"]
    assert k[0] == ["DIELECTRIC", "CONDUCTOR"]                                   # default stack
    assert k[1] == ["DIELECTRIC", "NULL", "CONDUCTOR"]                          # added below the top
    assert k[2] == ["DIELECTRIC", "NULL", "NULL", "CONDUCTOR"]                  # duplicated
    assert r["dup"] == ["NULL", 2.0, 0.5, "HG", 0.3]                            # with its medium
    assert k[3] == ["DIELECTRIC", "NULL", "CONDUCTOR", "NULL"] and r["active_after_move"] == 2
    assert k[4] == ["DIELECTRIC", "NULL", "NULL", "CONDUCTOR"]
    assert k[5] == ["DIELECTRIC", "NULL", "NULL"]
    assert r["top_up"] == ["CANCELLED"]
    assert len(set(r["names"])) == len(r["names"])                              # unique labels


def test_stack_panel(results):
    r = result_of(results, "stack_panel")
    calls = r["good"]["calls"]
    assert ["template_list", "LAMINA_UL_layers", "", "layers", "active_layer"] in calls
    assert {"ior", "roughness", "distribution", "thickness", "sigma_t", "albedo", "phase",
            "flake_stddev", "flake_orientation", "roughness_texture", "albedo_texture"} <= props_drawn(calls)
    ops = [c[1] for c in calls if c[0] in ("operator", "operator_menu_enum")]
    assert {"lamina.stack_add", "lamina.stack_remove", "lamina.stack_duplicate", "lamina.stack_move"} <= set(ops)
    assert ["menu", "LAMINA_MT_material_presets"] in calls
    assert not [f for f in r["good"]["findings"] if f[0] != "INFO"]
    odd = r["odd_findings"]
    assert any(level == "WARNING" and "opaque" in msg for level, msg in odd)
    assert any(c[0] == "label" and "opaque" in c[1] and c[2] == "ERROR" for c in r["odd_calls"])
    assert any("cycle" in msg for level, msg in r["cycle_findings"] if level == "ERROR")
    row = r["row"]
    assert row[0][:2] == ["prop", "name"] and any(c[0] == "label" and c[1].startswith("▼") for c in row)
    assert r["poll"] == {"lamina": True, "cycles": False, "none": False}
    assert any(c[0] == "label" and "Noise Texture" in c[1] for c in r["node_calls"])
    assert ["operator", "lamina.stack_new"] in r["node_calls"]
    assert ["menu", "LAMINA_MT_material_presets"] in r["node_calls"]     # presets for node materials too


def test_light_and_render_panels(results):
    r = result_of(results, "light_and_render_panels")
    assert {"energy", "color", "shadow_soft_size", "ies_mode"} <= props_drawn(r["POINT"])
    assert {"angle"} <= props_drawn(r["SUN"])
    assert {"shape", "size", "beam_mode", "beam_width", "cutoff_angle"} <= props_drawn(r["AREA"])
    assert r["beam_clamped"] == pytest.approx(0.3)
    assert r["ies_node"] == {"data": "IESNA:LM-63-2002\nTILT=NONE\n", "_node": "IES Texture"}  # (named in messages)
    assert r["unknown_icons"] == []          # every icon drawn so far (stack, lights, render) exists
    assert {"samples", "time_limit", "max_bounces", "seed", "workers", "noise_threshold",
            "estimator", "pdf_mode"} <= props_drawn(r["render"])


def test_presets_round_trip(results):
    r = result_of(results, "presets")
    assert r["again"] == r["doc"]
    assert r["status"] == ["FINISHED"] and r["from_op"] == r["doc"]
    assert r["doc"]["interfaces"][1]["roughness_v"] == pytest.approx(0.16)
    assert r["doc"]["emission"] == pytest.approx([2.0, 1.0, 0.5])
