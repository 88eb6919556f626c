"""Motion blur (``"motion"`` on objects and the camera) against a closed form.

A white-ish diffuse half-plane (x < 0 at the shutter's opening) slides +D along x while the
shutter is open, under a sun at the zenith, over a black world; an orthographic camera looks
down. A point at x ≥ 0 is covered for the part 1 − x/D of the shutter (0 ≤ x ≤ D), so its
expected radiance is ρ/π · E · (1 − x/D): a ramp. The pixel filter is symmetric, so a pixel
centred where the ramp is linear gets exactly the ramp's value. The same ramp comes from a
static plane and a camera sliding −D. σ of each column's mean from its pixels' sample variance.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from render_util import render, scene

ALBEDO = 0.6
E_SUN = math.pi                 # W/m²: radiance of the lit plane = albedo
D = 1.0                         # m, the slide over the shutter
W, H = 48, 8
X0, X1 = -1.0, 2.0              # the camera's view along x (m)


def _camera(shift: float = 0.0) -> dict:
    hw, hh = (X1 - X0) / 2, (X1 - X0) / 2 * H / W
    cx = (X0 + X1) / 2 + shift
    return {"type": "orthographic", "to_world": [[1, 0, 0, cx], [0, 1, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]],
            "frame": [[hw, hh, -1], [hw, -hh, -1], [-hw, -hh, -1], [-hw, hh, -1]]}


def _translation(x: float) -> list:
    return [[1, 0, 0, x], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


def _scene(plane_motion=None, camera_motion=None, spp=64) -> dict:
    mesh = {"positions": [[-20, -5, 0], [0, -5, 0], [0, 5, 0], [-20, 5, 0]],
            "indices": [[0, 1, 2], [0, 2, 3]]}
    obj = {"mesh": "half", "materials": ["m"]}
    if plane_motion is not None:
        obj["motion"] = plane_motion
    cam = _camera()
    if camera_motion is not None:
        cam["motion"] = camera_motion
    return scene(W, H, cam, {"m": {"type": "diffuse", "color": [ALBEDO] * 3}}, {"half": mesh}, [obj],
                 [{"type": "sun", "strength": E_SUN, "angle": 0.0, "to_world": np.eye(4).tolist()}],
                 world={"type": "constant", "color": [0, 0, 0]},
                 render={"spp": spp, "max_bounces": 0, "seed": 11})


def _columns(result):
    img = result.film.combined()[..., 0]
    var = result.film.variance_of_mean()[..., 0]
    x = X0 + (np.arange(W) + 0.5) * (X1 - X0) / W
    return x, img.mean(axis=0), np.sqrt(var.sum(axis=0)) / H


def _check_ramp(result):
    x, mean, se = _columns(result)
    expected = ALBEDO * np.clip(1.0 - x / D, 0.0, 1.0)
    # Columns whose filter footprint (≤ 2 pixels) stays on one linear piece of the ramp.
    px = (X1 - X0) / W
    inside = (np.abs(x) > 2 * px) & (np.abs(x - D) > 2 * px)
    z = (mean - expected)[inside] / np.maximum(se[inside], 1e-9)
    assert np.all(np.abs(z) < 4.5), np.round(z, 2)
    ramp = inside & (x > 0) & (x < D)
    assert ramp.sum() >= 10 and np.all(se[ramp] > 0)          # the blur is sampled, not constant
    return mean


@pytest.mark.parametrize("steps", [2, 5])
def test_a_sliding_plane_leaves_a_linear_ramp(steps):
    motion = [_translation(D * k / (steps - 1)) for k in range(steps)]
    _check_ramp(render(_scene(plane_motion=motion)))


def test_a_sliding_camera_blurs_like_the_scene_sliding_the_other_way():
    motion = [_camera(-D * k / 2)["to_world"] for k in range(3)]
    _check_ramp(render(_scene(camera_motion=motion)))


def test_without_motion_the_edge_stays_sharp():
    x, mean, _ = _columns(render(_scene(spp=16)))
    px = (X1 - X0) / W
    assert np.allclose(mean[x < -2 * px], ALBEDO, rtol=1e-6)
    assert np.all(mean[x > 2 * px] == 0.0)


def test_moving_object_in_two_worker_threads_is_bit_identical():
    motion = [_translation(D * k) for k in range(2)]
    data = _scene(plane_motion=motion, spp=8)
    a = render(data, workers=1).film.combined()
    b = render(data, workers=2).film.combined()
    assert np.array_equal(a, b)


def test_bad_motion_is_refused_with_its_path():
    from backend.errors import SceneError
    for motion, words in (([_translation(0)], "list of 2 to"), ([_translation(0), [[1, 0], [0, 1]]], "motion[1]")):
        with pytest.raises(SceneError) as err:
            render(_scene(plane_motion=motion))
        assert "objects[0].motion" in str(err.value) and words in str(err.value), str(err.value)
