"""Bake Procedural Textures: a procedural checker becomes an image the export uses and that
renders as Cycles renders the checker itself."""
from __future__ import annotations

import numpy as np
import pytest

from bpy_harness import backend_renders, requires_bpy, result_of, run_cases
from test_engine import channels_named, read_exr_parts

pytestmark = [pytest.mark.blender, requires_bpy]

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def test_baked_checker_is_exported_and_goes_stale_when_changed(tmp_path):
    r = result_of(run_cases("bake_cases", ["bake_and_export"], tmp=tmp_path), "bake_and_export")
    assert "Checker (Checker Texture) → Diffuse BSDF.Color (procedural, not baked" in r["before"]
    assert r["before_color"] == [0.5, 0.5, 0.5]                 # the socket's value
    assert r["operator"] == ["FINISHED"] and r["image"] and r["packed"]
    # The checker's two colours (texel centres never fall on a square's edge at 64² and scale 4)
    assert r["texel_values"] == [0.1, 0.8], r["texel_values"]
    # The operator leaves the material and the scene as they were.
    assert r["nodes_after"] == sorted(["ShaderNodeBsdfDiffuse", "ShaderNodeOutputMaterial", "ShaderNodeTexChecker"])
    assert "Lamina bake object" not in r["objects_after"]
    assert r["after"] is None or "Checker" not in r["after"]
    assert isinstance(r["after_color"], dict) and r["after_color"]["texture"]
    assert "Checker (Checker Texture) → Diffuse BSDF.Color (changed since it was baked" in r["stale"]
    assert r["stale_color"] == [0.5, 0.5, 0.5]


@pytest.mark.slow
@pytest.mark.skipif(not backend_renders(("diffuse",)), reason="backend cannot render")
def test_baked_checker_renders_like_cycles(tmp_path):
    """Region means of a checkered plane under a sun within 2 % (or 4σ) of Cycles', in 4 × 4
    blocks that each hold whole checker squares and edges."""
    r = result_of(run_cases("bake_cases", ["checker_parity"], tmp=tmp_path, timeout=900), "checker_parity")
    assert r["operator"] == ["FINISHED"]
    assert r["cycles_error"] is None and r["lamina_error"] is None, r
    cyc = channels_named(read_exr_parts(r["cycles"]), ["R", "G", "B"]).astype(np.float64) @ LUMINANCE
    lam = channels_named(read_exr_parts(r["lamina"]), ["R", "G", "B"]).astype(np.float64) @ LUMINANCE
    h, w = cyc.shape
    lines, bad = [], []
    # The plane fills the middle of the frame; blocks of 8 × 8 pixels inside it.
    for y in range(16, 48, 8):
        for x in range(16, 48, 8):
            c, l = cyc[y:y + 8, x:x + 8], lam[y:y + 8, x:x + 8]
            diff = (l - c).ravel()
            se = diff.std(ddof=1) / np.sqrt(diff.size) / c.mean()
            ratio = l.mean() / c.mean()
            lines.append(f"  block ({x}, {y}) Lamina/Cycles {ratio:.4f} ± {se:.4f}")
            if abs(ratio - 1) > max(0.02, 4 * se):
                bad.append(lines[-1])
    print("\nBaked checker:\n" + "\n".join(lines))
    assert not bad, "\n".join(bad)
    assert cyc[16:48, 16:48].max() > 3 * cyc[16:48, 16:48].min()      # the checker shows


def test_bake_writes_only_the_material_faces_and_skips_objects_without_uvs(tmp_path):
    r = result_of(run_cases("bake_cases", ["bake_awkward"], tmp=tmp_path), "bake_awkward")
    assert r["image"]
    assert r["left_values"] == [0.1, 0.8]          # the checker where its faces lie
    assert r["right_values"] == [0.0]              # the other material's faces: not baked over
    assert not r["no_uv_baked"]
    assert "Lamina bake object" not in r["objects"] and r["meshes"] == 2


def test_export_operator_bakes_what_is_missing(tmp_path):
    r = result_of(run_cases("bake_cases", ["export_operator_bakes"], tmp=tmp_path), "export_operator_bakes")
    assert r["first"] == ["FINISHED"]
    assert isinstance(r["color"], dict) and r["color"]["texture"]       # the baked image, not 0.5
    assert r["size"] == [32, 32]
    assert r["again"] == 0                     # up to date: nothing baked twice
    assert r["off"] == ["FINISHED"] and r["off_color"] == [0.5, 0.5, 0.5]
    assert "changed since it was baked" in r["off_warning"]
    assert r["stale_baked"] == 1               # a changed input is baked again
