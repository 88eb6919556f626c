"""The denoiser's features (albedo, normal) follow mirrors and smooth glass to the first other
surface, as Cycles' denoising features do: behind a mirror OIDN then sees the texture and shape
of what the mirror shows instead of a flat white plane."""
from __future__ import annotations

import math

import numpy as np

from render_util import quad, render, scene

WALL = [0.2, 0.4, 0.6]
S2 = 1.0 / math.sqrt(2.0)


def _mirror_scene(mirror: dict) -> dict:
    """A camera looking down −Z at a 45° mirror that sends its rays along −Y to a diffuse wall."""
    camera = {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
              "frame": [[0.1, 0.1, -1], [0.1, -0.1, -1], [-0.1, -0.1, -1], [-0.1, 0.1, -1]]}
    meshes = {"mirror": quad([0, 0, -2], [1, 0, 0], [0, S2, S2]),
              "wall": quad([0, -3, -2], [5, 0, 0], [0, 0, 8])}
    return scene(8, 8, camera, {"mirror": mirror, "wall": {"type": "diffuse", "color": WALL}}, meshes,
                 [{"name": "mirror", "mesh": "mirror", "materials": ["mirror"]},
                  {"name": "wall", "mesh": "wall", "materials": ["wall"]}],
                 world={"type": "constant", "color": [0.5, 0.5, 0.5]}, render={"spp": 4, "max_bounces": 4})


def test_features_behind_a_mirror_are_those_of_what_it_shows():
    # k ≫ 1: a mirror that reflects all but ~1e-8 of the light, so the albedo behind it is the wall's.
    mirror = {"type": "conductor", "eta": [1.0, 1.0, 1.0], "k": [1e4, 1e4, 1e4], "roughness": 0.0}
    film = render(_mirror_scene(mirror)).film
    albedo = film.albedo_image().reshape(-1, 3)
    normal = film.normal_image().reshape(-1, 3)
    np.testing.assert_allclose(albedo, np.tile(WALL, (albedo.shape[0], 1)), rtol=1e-6)
    np.testing.assert_allclose(normal, np.tile([0.0, 1.0, 0.0], (normal.shape[0], 1)), atol=1e-6)


def test_a_rough_mirror_keeps_its_own_features():
    """Only delta surfaces pass the features on: a glossy mirror is what the denoiser sees."""
    mirror = {"type": "conductor", "eta": [1.0, 1.0, 1.0], "k": [1e4, 1e4, 1e4], "roughness": 0.3}
    film = render(_mirror_scene(mirror)).film
    normal = film.normal_image().reshape(-1, 3)
    np.testing.assert_allclose(normal, np.tile([0.0, -S2, S2], (normal.shape[0], 1)), atol=1e-6)
    assert np.all(film.albedo_image() > 0.9)
