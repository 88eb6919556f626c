"""Light fields in scene files: Blender's units converted in one place, clear errors."""
import copy

import numpy as np
import pytest

from backend.errors import SceneError
from backend.lights.area import AreaLight, CollimatedAreaLight
from backend.lights.point import PointLight
from backend.lights.profiles import CyclesSpread, Lambertian, SmoothCone
from backend.lights.spot import SpotLight
from backend.lights.sun import SunLight
from backend.scene.loader import load_scene_data

M = [[1, 0, 0, 0.5], [0, 2, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]
BASE = {
    "format": "lamina-scene", "version": 1, "film": {"width": 4, "height": 4},
    "camera": {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0, -1, -5], [0, 1, 0, 0], [0, 0, 0, 1]],
               "frame": [[0.36, 0.27, -1], [0.36, -0.27, -1], [-0.36, -0.27, -1], [-0.36, 0.27, -1]]},
}


def load(*lights, world=None):
    data = copy.deepcopy(BASE)
    data["lights"] = list(lights)
    if world is not None:
        data["world"] = world
    return load_scene_data(data, "scene.json")


def test_each_light_type_parses_with_blender_units():
    scene = load({"type": "point", "to_world": M, "power": 100, "color": [1, 0.5, 0.25], "radius": 0.1,
                  "soft_falloff": True, "visible_camera": True},
                 {"type": "spot", "to_world": M, "power": 100, "spot_size": 60, "spot_blend": 0.2},
                 {"type": "sun", "to_world": M, "strength": 3, "angle": 0.526},
                 {"type": "area", "to_world": M, "shape": "rectangle", "size": 1.0, "size_y": 0.5, "power": 10},
                 {"type": "area", "to_world": M, "shape": "disk", "size": 1.0, "size_y": 7, "power": 10,
                  "spread": 30},
                 {"type": "area", "to_world": M, "power": 10, "cutoff_angle": 30, "beam_width": 10},
                 {"type": "area", "to_world": M, "power": 10, "spread": 0},
                 world={"type": "constant", "color": [0.1, 0.2, 0.3], "strength": 2})
    point, spot, sun, rect, disk, dv, flat = scene.lights[:7]
    assert isinstance(point, PointLight) and point.soft_falloff and point.visible_camera
    assert np.allclose(point.radiance, np.array([1, 0.5, 0.25]) * 100 / (4 * np.pi ** 2 * 0.01))
    assert isinstance(spot, SpotLight) and spot.cos_half == pytest.approx(np.cos(np.radians(30)))
    assert not spot.visible_camera          # Blender 5.0's default for light objects
    assert isinstance(sun, SunLight) and sun.angle == pytest.approx(np.radians(0.526))
    assert isinstance(rect, AreaLight) and rect.geo.area == pytest.approx(1.0 * 2 * 0.5)   # scale (1, 2)
    assert isinstance(disk.profile, CyclesSpread) and disk.geo.area == pytest.approx(np.pi / 4 * 1 * 2)
    assert isinstance(dv.profile, SmoothCone) and isinstance(rect.profile, Lambertian)
    assert isinstance(flat, CollimatedAreaLight)
    assert np.allclose(scene.world.radiance, [0.2, 0.4, 0.6])


@pytest.mark.parametrize("light, message", [
    ({"type": "point", "to_world": M}, "lights[0].power: missing required field"),
    ({"type": "point", "to_world": M, "power": 1, "radius": -1}, "lights[0].radius: expected a number >= 0"),
    ({"type": "point", "to_world": M, "power": 1, "colour": [1, 1, 1]}, "lights[0].colour: unknown field"),
    ({"type": "spot", "to_world": M, "power": 1, "spot_size": 200}, "lights[0].spot_size: expected a number in [1, 180]"),
    ({"type": "spot", "to_world": M, "power": 1, "spot_blend": 1.5}, "lights[0].spot_blend: expected a number in [0, 1]"),
    ({"type": "sun", "to_world": M, "strength": 1, "angle": -1}, "lights[0].angle: expected a number in [0, 180]"),
    ({"type": "area", "to_world": M, "power": 1, "shape": "circle"}, "lights[0].shape: expected one of"),
    ({"type": "area", "to_world": M, "power": 1, "spread": 30, "cutoff_angle": 20},
     "lights[0].spread: give either spread or cutoff_angle/beam_width, not both"),
    ({"type": "area", "to_world": M, "power": 1, "cutoff_angle": 20, "beam_width": 30},
     "lights[0].beam_width: expected a number <= cutoff_angle (20), got 30"),
    ({"type": "area", "to_world": M, "power": 1, "cutoff_angle": 0}, "lights[0].cutoff_angle: expected a number in (0, 90]"),
    ({"type": "point", "to_world": M, "power": 1, "ies": {"file": "x.ies"}}, "lights[0].ies"),
    ({"type": "laser", "to_world": M}, "lights[0].type: unknown type 'laser'"),
])
def test_light_field_errors(light, message):
    with pytest.raises(SceneError) as info:
        load(light)
    assert str(info.value).startswith(f"scene.json: {message}"), str(info.value)


def test_world_errors(tmp_path):
    # A missing environment map renders magenta with a warning (as Cycles), or fails the load
    # with render.missing_textures "error" (the CLI's --strict).
    scene = load(world={"type": "environment", "file": "missing.exr"})
    assert any("world.file" in w and "not found" in w and "magenta" in w for w in scene.warnings), scene.warnings
    data = copy.deepcopy(BASE)
    data["world"] = {"type": "environment", "file": "missing.exr"}
    data["render"] = dict(data.get("render", {}), missing_textures="error")
    with pytest.raises(SceneError) as info:
        load_scene_data(data, "scene.json")
    assert "world.file" in str(info.value) and "not found" in str(info.value)
    with pytest.raises(SceneError) as info:
        load(world={"type": "constant", "strength": -1})
    assert "world.strength: expected a number >= 0" in str(info.value)
