"""Malformed scenes give one clear error naming the file and the field path (never a traceback)."""
import copy
import json
import subprocess
import sys

import numpy as np
import pytest

from backend.errors import SceneError
from backend.scene.loader import load_scene, load_scene_data

from conftest import ROOT

BASE = {
    "format": "lamina-scene", "version": 1,
    "film": {"width": 32, "height": 24},
    "camera": {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0, -1, -5], [0, 1, 0, 0], [0, 0, 0, 1]],
               "frame": [[0.36, 0.27, -1], [0.36, -0.27, -1], [-0.36, -0.27, -1], [-0.36, 0.27, -1]]},
    "materials": {"grey": {"type": "diffuse", "color": 0.5}},
    "meshes": {"tri": {"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "indices": [[0, 1, 2]]}},
    "objects": [{"mesh": "tri", "materials": ["grey"]}],
    "world": {"type": "constant", "color": [1, 1, 1], "strength": 1},
}


def scene_with(edit):
    data = copy.deepcopy(BASE)
    edit(data)
    return data


def error_of(data, tmp_path=None) -> str:
    with pytest.raises(SceneError) as info:
        load_scene_data(data, "scene.json", tmp_path)
    return str(info.value)


def test_base_scene_loads():
    scene = load_scene_data(copy.deepcopy(BASE), "scene.json")
    assert scene.soup.count == 1
    assert scene.warnings == []


@pytest.mark.parametrize("edit, expected", [
    (lambda d: d.pop("film"), "scene.json: film: missing required field"),
    (lambda d: d.update(flim={}), "scene.json: flim: unknown field"),
    (lambda d: d["film"].update(width="640"), "scene.json: film.width: expected an integer"),
    (lambda d: d["film"].update(height=0), "scene.json: film.height: expected an integer in [1, 65536], got 0"),
    (lambda d: d.update(version=2), "scene.json: version: unsupported scene version 2 (this Lamina reads version 1)"),
    (lambda d: d.update(format="other"), "scene.json: format: expected 'lamina-scene'"),
    (lambda d: d["camera"].update(type="fisheye"), "scene.json: camera.type: expected one of 'perspective', 'orthographic'"),
    (lambda d: d["camera"]["frame"].pop(), "scene.json: camera.frame: expected 4 corners"),
    (lambda d: d["camera"].update(to_world=[[1, 0], [0, 1]]), "scene.json: camera.to_world: expected a 4×4 matrix"),
    (lambda d: d["materials"]["grey"].update(color=-0.3), "scene.json: materials.grey.color[0]: expected a number >= 0, got -0.3"),
    (lambda d: d["materials"]["grey"].update(colour=1), "scene.json: materials.grey.colour: unknown field"),
    (lambda d: d["materials"]["grey"].update(type="velvet"), "scene.json: materials.grey.type: unknown type 'velvet'"),
    (lambda d: d["meshes"]["tri"].update(indices=[[0, 1, 3]]), "scene.json: meshes.tri.indices: indices[0] = [0, 1, 3] out of bounds for 3 vertices"),
    (lambda d: d["meshes"]["tri"].update(indices=[]), "scene.json: meshes.tri.indices: indices: expected integer shape (T, 3)"),
    (lambda d: d["meshes"]["tri"].update(positions=[[0, 0, 0], [1, 0, 0], [0, "a", 0]]), "scene.json: meshes.tri.positions: positions[2][1]: expected a finite number, got 'a'"),
    (lambda d: d["meshes"]["tri"].update(positions=[[0, 0, 0], [1, 0, 0], [0, 1]]), "scene.json: meshes.tri.positions: expected a rectangular list of numbers"),
    (lambda d: d["objects"][0].update(mesh="box"), "scene.json: objects[0].mesh: unknown mesh 'box'"),
    (lambda d: d["objects"][0].update(materials=["gold"]), "scene.json: objects[0].materials[0]: unknown material 'gold'"),
    (lambda d: d.update(render={"spp": 0}), "scene.json: render.spp: expected an integer in [1, 16777216], got 0"),
    (lambda d: d.update(render={"noise_target": float("nan")}), "scene.json: render.noise_target: expected a number in [0, 1], got nan"),
])
def test_malformed_scene_errors(edit, expected):
    message = error_of(scene_with(edit))
    assert message.startswith(expected), message


def test_nan_vertices_in_npz(tmp_path):
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], np.float32)
    np.savez(tmp_path / "m.npz", positions=pos, indices=np.array([[0, 1, 2]], np.int32))
    data = scene_with(lambda d: d["meshes"].update(tri={"file": "m.npz"}))
    message = error_of(data, tmp_path)
    assert message == "scene.json: meshes.tri.file: m.npz: positions[2] is not finite (NaN or Inf)"


def test_nan_normals_inline():
    data = scene_with(lambda d: d["meshes"]["tri"].update(normals=[[0, 0, 1], [0, 0, 1], [0, 0, float("inf")]]))
    assert "meshes.tri.normals: normals[2][2]: expected a finite number, got inf" in error_of(data)


def test_missing_mesh_file(tmp_path):
    data = scene_with(lambda d: d["meshes"].update(tri={"file": "nope.npz"}))
    assert "scene.json: meshes.tri.file: mesh file not found" in error_of(data, tmp_path)


def test_missing_texture_file(tmp_path):
    data = scene_with(lambda d: d["materials"]["grey"].update(color={"texture": "wood.png"}))
    # Default: magenta, one warning (as Cycles); render.missing_textures "error": a load error.
    scene = load_scene_data(data, "scene.json", tmp_path)
    assert len(scene.warnings) == 1 and "texture file not found" in scene.warnings[0]
    assert scene.warnings[0].startswith("scene.json: materials.grey.color.texture: ")
    data["render"] = dict(data.get("render", {}), missing_textures="error")
    message = error_of(data, tmp_path)
    assert message.startswith("scene.json: materials.grey.color.texture: texture file not found")
    data["render"]["missing_textures"] = "ignore"
    assert "render.missing_textures: expected one of" in error_of(data, tmp_path)


def test_strict_cli_makes_a_missing_texture_an_error(tmp_path):
    import json
    import subprocess
    import sys
    data = scene_with(lambda d: d["materials"]["grey"].update(color={"texture": "wood.png"}))
    (tmp_path / "s.json").write_text(json.dumps(data))
    run = lambda *extra: subprocess.run([sys.executable, "-m", "backend", "validate", str(tmp_path / "s.json"),
                                         *extra], capture_output=True, text=True)
    lenient, strict = run(), run("--strict")
    assert lenient.returncode == 0 and "rendered magenta" in lenient.stderr, lenient.stderr
    assert strict.returncode == 2 and "texture file not found" in strict.stderr, strict.stderr
    assert "Traceback" not in strict.stderr


def test_degenerate_triangles_dropped_with_warning():
    data = scene_with(lambda d: d["meshes"]["tri"].update(
        positions=[[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], indices=[[0, 1, 2], [0, 1, 3]]))
    scene = load_scene_data(data, "scene.json")
    assert scene.soup.count == 1
    assert scene.warnings == ["scene.json: meshes.tri: 1 degenerate (zero-area) triangle(s) dropped"]


def test_all_degenerate_is_an_empty_mesh_error():
    data = scene_with(lambda d: d["meshes"]["tri"].update(positions=[[0, 0, 0], [1, 0, 0], [2, 0, 0]]))
    assert "meshes.tri: every triangle is degenerate" in error_of(data)


def test_missing_material_slot_falls_back_with_warning():
    data = scene_with(lambda d: d["objects"][0].pop("materials"))
    scene = load_scene_data(data, "scene.json")
    assert scene.material_names[-1] == "<default>"
    assert "material slot that is not set" in scene.warnings[0]


def test_invalid_json_reports_line(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"format": "lamina-scene",\n "version": 1,,}')
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert "not valid JSON" in str(info.value) and "line 2" in str(info.value)


def test_cli_reports_error_in_one_line_without_traceback(tmp_path):
    data = scene_with(lambda d: d["materials"]["grey"].update(color=-0.3))
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(data))
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(path), "-o", str(tmp_path / "x.exr")],
                          cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert lines == [f"error: {path}: materials.grey.color[0]: expected a number >= 0, got -0.3"]


def test_lights_that_all_emit_nothing_are_warned_about():
    """A black image must not come silently: every emitter black or at strength 0 is a warning;
    one emitting light (here a dim blue point light, or an emissive material) clears it."""
    point = {"type": "point", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 2], [0, 0, 0, 1]],
             "power": 0.0, "color": [1, 1, 1]}
    dark = scene_with(lambda d: d.update(world={"type": "constant", "color": [0, 0, 0], "strength": 1},
                                         lights=[point]))
    per_light, warning = load_scene_data(dark, "scene.json").warnings
    assert per_light == "scene.json: lights[0]: light emits nothing (power 0): it is dark"
    assert "every light in the scene emits nothing" in warning and "2 checked" in warning
    dim_blue = copy.deepcopy(dark)
    dim_blue["lights"][0].update(power=1e-3, color=[0, 0, 1])
    assert load_scene_data(dim_blue, "scene.json").warnings == []
    glowing = copy.deepcopy(dark)
    glowing["materials"]["grey"]["emission"] = [0.0, 0.5, 0.0]
    assert load_scene_data(glowing, "scene.json").warnings == [per_light]   # that light is still dark
    zero_strength = scene_with(lambda d: d["world"].update(strength=0))
    assert "emits nothing" in load_scene_data(zero_strength, "scene.json").warnings[0]
