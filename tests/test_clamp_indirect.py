"""Clamp Indirect (``render.clamp``; kernels/integrator.py ``_clamped``) as Cycles defines it: the
light a path gathers at a vertex after the camera's hit is scaled so that the sum of its RGB is at
most the clamp; the camera hit's own light — its light samples and the emission its continuation
ray finds — is direct light and never clamped (Cycles clamps emission found by a path with the
bounce of the vertex the ray left). Checked against renders that hold the same light without any
clamp, region by region, within the renders' own standard errors."""
from __future__ import annotations

import numpy as np
from scipy.stats import norm

from backend.kernels.integrator import _clamped
from render_util import look_down_ortho, quad, region_z, render, scene
from stats_util import sidak

BLOCKS = 4
SUN = {"type": "sun", "strength": 3.0, "angle": 5.0,
       "to_world": [[1, 0, 0, 0], [0, 0.8, -0.6, 0], [0, 0.6, 0.8, 10], [0, 0, 0, 1]]}
# Large and near: over the plane below it, BSDF sampling's MIS weight is about 0.9 (the light's
# pdf, distance² / (area · cos), is small against the cosine's), so most of its light is found
# by the camera hit's continuation ray.
LAMP = {"type": "area", "shape": "square", "size": 4.0, "power": 300.0,
        "to_world": [[1, 0, 0, 0.3], [0, 1, 0, 0.2], [0, 0, 1, 1.0], [0, 0, 0, 1]]}


def _z_limit(z: np.ndarray) -> float:
    """|z| every region and channel stays below at a family-wise level of 0.1 % (two-sided)."""
    return float(norm.isf(sidak(0.001, z.size) / 2))


def test_the_clamp_sums_rgb_and_spares_the_camera_hit():
    assert _clamped((3.0, 1.0, 0.0), 2.0, 1) == (1.5, 0.5, 0.0)
    # the sum, not the largest channel: grey light of 1 per channel is 3 > 2
    np.testing.assert_allclose(_clamped((1.0, 1.0, 1.0), 2.0, 2), (2 / 3, 2 / 3, 2 / 3), rtol=1e-15)
    assert _clamped((3.0, 1.0, 0.0), 2.0, 0) == (3.0, 1.0, 0.0)       # the camera hit's light
    assert _clamped((3.0, 1.0, 0.0), 2.0, -1) == (3.0, 1.0, 0.0)      # what the camera sees
    assert _clamped((3.0, 1.0, 0.0), 0.0, 1) == (3.0, 1.0, 0.0)       # off


def _plane(clamp: float, seed: int, spp: int = 64) -> dict:
    """A diffuse plane and a rough gold one seen from above under a lamp and a sun, nothing else:
    all of their light is direct."""
    return scene(24, 24, look_down_ortho(1.0),
                 {"grey": {"type": "diffuse", "color": [0.7, 0.7, 0.7]},
                  "gold": {"type": "conductor", "metal": "Au", "roughness": 0.3}},
                 {"left": quad([-0.6, 0, 0], [0.6, 0, 0], [0, 1.2, 0]), "right": quad([0.6, 0, 0], [0.6, 0, 0], [0, 1.2, 0])},
                 [{"mesh": "left", "materials": ["grey"]}, {"mesh": "right", "materials": ["gold"]}],
                 [LAMP, SUN], render={"spp": spp, "max_bounces": 4, "seed": seed, "clamp": clamp})


def test_direct_light_is_never_clamped():
    clamped = render(_plane(1e-9, 11))
    free = render(_plane(0.0, 12))
    z = region_z(clamped, free, BLOCKS)
    assert z.max() < _z_limit(z), z.max()


def _corner(clamp: float, max_bounces: int, seed: int, spp: int = 64) -> dict:
    """A sunlit floor and wall seen from above at an angle: the floor also gets the wall's light."""
    grey = {"type": "diffuse", "color": [0.6, 0.6, 0.6]}
    return scene(24, 24, look_down_ortho(1.0), {"grey": grey},
                 {"floor": quad([0, 0, 0], [1.5, 0, 0], [0, 1.5, 0]),
                  "wall": quad([0, 0.9, 0.5], [1.5, 0, 0], [0, 0, 0.5])},
                 [{"mesh": "floor", "materials": ["grey"]}, {"mesh": "wall", "materials": ["grey"]}],
                 [SUN], world={"type": "constant", "color": [0.2, 0.25, 0.3]},
                 render={"spp": spp, "max_bounces": max_bounces, "seed": seed, "clamp": clamp})


def test_a_vanishing_clamp_leaves_the_direct_light():
    """Clamped to nothing, every bounce after the camera's hit adds nothing: the image is the
    direct light alone, which max_bounces 0 renders without any clamp (the camera hit's light
    samples and the emission its continuation finds). And there is indirect light to clamp."""
    clamped = render(_corner(1e-9, 8, 21))
    direct = render(_corner(0.0, 0, 22))
    z = region_z(clamped, direct, BLOCKS)
    assert z.max() < _z_limit(z), z.max()
    full = render(_corner(0.0, 8, 23))
    assert full.film.combined()[..., :3].mean() > 1.05 * direct.film.combined()[..., :3].mean()
