"""Whole-material normal maps (``"normal"`` / ``"normal_strength"`` on any material; Blender's
Normal Map node in tangent space) against closed forms.

A Lambertian plane z = 0 with UVs (tangent +X, so the map's x is world +X and its y world +Y)
under a delta sun, direct light only, seen from above: every pixel is albedo/π · E · cos between
the shading normal and the sun, exactly (no random number touches it).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from render_util import assert_no_gain_in_white_furnace, look_down_ortho, render, scene

ALBEDO = 0.5
E_SUN = 3.0                    # W/m², the sun's irradiance (its strength)
SUN_TILT = math.radians(40)    # the sun's direction: 40° from the zenith towards +X


def _sun(tilt: float = SUN_TILT) -> dict:
    c, s = math.cos(tilt), math.sin(tilt)
    # A sun shines along its local −Z: rotated about Y by the tilt, it comes from (sin, 0, cos).
    return {"type": "sun", "strength": E_SUN, "angle": 0.0,
            "to_world": [[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]]}


def _plane_scene(material: dict, spp: int = 4) -> dict:
    mesh = {"positions": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]],
            "indices": [[0, 1, 2], [0, 2, 3]], "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]]}
    return scene(16, 16, look_down_ortho(1.0), {"m": material}, {"plane": mesh},
                 [{"mesh": "plane", "materials": ["m"]}], [_sun()],
                 render={"spp": spp, "max_bounces": 0, "seed": 3})


def _expected(normal) -> float:
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    sun = np.array([math.sin(SUN_TILT), 0.0, math.cos(SUN_TILT)])
    return ALBEDO / math.pi * E_SUN * max(float(n @ sun), 0.0)


def _image(material: dict) -> np.ndarray:
    return render(_plane_scene(material)).film.combined()[..., :3]


TILTED = [math.sin(math.radians(25)), 0.0, math.cos(math.radians(25))]      # 25° towards +X


def test_constant_normal_map_turns_the_shading_normal():
    plain = _image({"type": "diffuse", "color": [ALBEDO] * 3})
    mapped = _image({"type": "diffuse", "color": [ALBEDO] * 3, "normal": TILTED})
    np.testing.assert_allclose(plain, _expected([0, 0, 1]), rtol=1e-5)
    np.testing.assert_allclose(mapped, _expected(TILTED), rtol=1e-5)       # cos 15° instead of cos 40°
    # tilted along y (the map's green channel is +Y here): the sun lies in the XZ plane
    side = [0.0, math.sin(math.radians(30)), math.cos(math.radians(30))]
    np.testing.assert_allclose(_image({"type": "diffuse", "color": [ALBEDO] * 3, "normal": side}),
                               _expected(side), rtol=1e-5)


def test_normal_map_texture_and_strength(tmp_path):
    """A uniform image encoding the tilted normal (RGB = (n + 1)/2, float EXR: read as stored)
    equals the constant; strength k mixes as Cycles: normalize(n + k·(mapped − n))."""
    from backend.imageio import write_exr
    path = tmp_path / "normal.exr"
    rgb = (np.asarray(TILTED) + 1.0) / 2.0
    write_exr(path, {"": np.broadcast_to(rgb, (4, 4, 3)).astype(np.float32)})
    textured = {"type": "diffuse", "color": [ALBEDO] * 3, "normal": {"texture": str(path)}}
    np.testing.assert_allclose(_image(textured), _expected(TILTED), rtol=1e-4)
    half = dict(textured, normal_strength=0.5)
    mixed = np.asarray([0, 0, 1]) + 0.5 * (np.asarray(TILTED) - np.asarray([0, 0, 1]))
    np.testing.assert_allclose(_image(half), _expected(mixed), rtol=1e-4)
    none = dict(textured, normal_strength=0.0)
    np.testing.assert_allclose(_image(none), _expected([0, 0, 1]), rtol=1e-5)


@pytest.mark.parametrize("material", [
    {"type": "conductor", "metal": "Ag", "roughness": 0.3},
    {"type": "conductor", "metal": "Ag", "roughness": 0.0},
    {"type": "dielectric", "ior": 1.5, "roughness": 0.2},
], ids=["rough-silver", "mirror", "rough-glass"])
def test_normal_mapped_materials_create_no_energy_under_a_white_furnace(material):
    """A tilted map (30°) on a closed sphere under a constant white world: no pixel
    above the world's radiance by more than 4σ (σ from the pixel's own sample variance), no NaN,
    and the sphere is not black."""
    n = [math.sin(math.radians(30)), 0.0, math.cos(math.radians(30))]
    assert_no_gain_in_white_furnace(dict(material, normal=n))
