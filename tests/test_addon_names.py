"""The add-on's messages in Blender's terms (addon/export/names.py, no bpy): a backend message's
field path becomes the material, node or light the user knows, once."""
from __future__ import annotations

import importlib.util
import json

import pytest

from conftest import ROOT

spec = importlib.util.spec_from_file_location("addon_names", ROOT / "addon" / "export" / "names.py")
names = importlib.util.module_from_spec(spec)
spec.loader.exec_module(names)

IES = "IESNA:LM-63-2002\nTILT=NONE\n1 1000 1 3 1 1 2 0.1 0.1 0\n1 1 100\n0 45 90\n0\n1000 600 100\n"


def _doc(ies: dict) -> dict:
    eye = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]
    return {"format": "lamina-scene", "version": 1, "film": {"width": 4, "height": 4},
            "camera": {"type": "perspective", "to_world": eye,
                       "frame": [[0.5, 0.5, -1], [0.5, -0.5, -1], [-0.5, -0.5, -1], [-0.5, 0.5, -1]]},
            "lights": [{"_name": "Lamp", "type": "spot", "to_world": eye, "power": 10.0, "ies": ies}]}


def _backend_message(doc: dict, tmp_path) -> str:
    from backend.errors import SceneError
    from backend.scene.loader import load_scene
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    return str(info.value)


@pytest.mark.parametrize("source, expected", [
    ({"_node": "Beam Shape"}, "light 'Lamp', node 'Beam Shape': "),
    ({}, "light 'Lamp', IES profile set in Lamina's light panel: "),
])
def test_an_ies_error_names_where_the_profile_came_from(tmp_path, source, expected):
    doc = _doc({"file": str(tmp_path / "missing.ies"), **source})
    message = _backend_message(doc, tmp_path)            # the backend's own words, real
    assert "lights[0].ies.file" in message
    described = names.FieldNames().collect(doc, {}, "", None).describe(message)
    assert described.startswith(expected), described
    assert "(ies.file)" not in described and "scene.json" not in described
    assert described.count("missing.ies") == 1


def test_the_light_itself_keeps_its_field_path():
    doc = _doc({"data": IES})
    text = names.FieldNames().collect(doc, {}, "", None).describe(
        "/tmp/x/scene.json: lights[0].power: expected a number >= 0, got -1")
    assert text == "light 'Lamp' (power): expected a number >= 0, got -1"
