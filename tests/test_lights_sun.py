"""Sun light: irradiance E cos θ (Cycles: strength = irradiance; disk radiance E/(π sin²(a/2)))."""
import numpy as np
import pytest

from backend.lights.sun import SunLight

from lights_util import K_SIGMA, chi2_directions, frame, nee_irradiance, rot_x, translate

E = 3.0
COLOR = np.array([1.0, 0.9, 0.7])


def test_delta_sun_irradiance():
    m = translate(0, 0, 5, rot_x(35))          # light travels along local −Z, rotated 35° about X
    sun = SunLight(m, E, COLOR)
    pts = np.random.default_rng(0).normal(size=(10, 3))
    s = sun.sample(pts, np.zeros((10, 2)))
    assert np.allclose(s.wi, [0, -np.sin(np.radians(35)), np.cos(np.radians(35))])
    assert np.allclose(s.value * s.wi[:, 2:3], COLOR * E * np.cos(np.radians(35)), rtol=1e-12)
    assert sun.is_delta and np.all(s.pdf == 0) and np.all(np.isinf(s.dist))
    assert np.all(sun.eval_escaped(s.wi) == 0) and np.all(sun.pdf_escaped(s.wi) == 0)


@pytest.mark.parametrize("angle_deg, tilt", [(0.53, 20.0), (10.0, 0.0), (60.0, 25.0)])
def test_sun_with_angle_irradiance_and_mis(angle_deg, tilt):
    """A receiver that sees the whole disk gets E cos θ, from NEE and from escaping cosine rays."""
    sun = SunLight(translate(0, 0, 0, rot_x(tilt)), E, COLOR, np.radians(angle_deg))
    rng = np.random.default_rng(1)
    normal = np.array([0.0, 0.0, 1.0])
    expected = COLOR * E * np.cos(np.radians(tilt))
    mean, se, s = nee_irradiance(sun, [0, 0, 0], normal, 20000, rng)
    assert np.all(np.abs(mean - expected) <= K_SIGMA * se + 1e-12 * expected), (mean, expected, se)
    # escaped rays: cosine sampling about the sun direction, weight L / pdf_cos
    axis = sun.direction
    s_, t_, n_ = frame(axis)
    n = 200000
    u = rng.random((n, 2))
    # sample directions uniformly in a cone slightly wider than the disk, weight by 1/pdf
    half = np.radians(angle_deg) / 2 * 1.2
    z = 1 - u[:, 0] * (1 - np.cos(half))
    r = np.sqrt(1 - z * z)
    d = (r * np.cos(2 * np.pi * u[:, 1]))[:, None] * s_ + (r * np.sin(2 * np.pi * u[:, 1]))[:, None] * t_ + z[:, None] * n_
    pdf = 1 / (2 * np.pi * (1 - np.cos(half)))
    e = sun.eval_escaped(d) * np.maximum(d @ normal, 0)[:, None] / pdf
    assert np.all(np.abs(e.mean(axis=0) - expected) <= K_SIGMA * e.std(axis=0) / np.sqrt(n) + 1e-12)
    # MIS consistency: the density of sample() is what pdf_escaped reports
    assert np.allclose(sun.pdf_escaped(s.wi), s.pdf, rtol=1e-12)
    assert np.allclose(sun.eval_escaped(s.wi) / s.pdf[:, None], s.value, rtol=1e-12)


@pytest.mark.parametrize("angle_deg", [0.53, 30.0])
def test_sun_sampling_chi2(angle_deg):
    sun = SunLight(translate(0, 0, 0, rot_x(40)), E, COLOR, np.radians(angle_deg))
    rng = np.random.default_rng(2)
    p_value, outside, mass = chi2_directions(sun, np.zeros(3), sun.direction,
                                             np.cos(np.radians(angle_deg) / 2), 100000, rng)
    assert outside == 0 and abs(mass - 1) < 1e-3 and p_value > 0.01, (p_value, outside, mass)


def test_sun_power_uses_scene_radius():
    sun = SunLight(np.eye(4), 2.0, [1, 1, 1], np.radians(1.0))
    sun.prepare(np.zeros(3), 10.0)
    assert sun.power() == pytest.approx(2.0 * np.pi * 100.0)
