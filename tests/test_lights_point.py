"""Point, sphere and soft-falloff point lights against closed forms (Cycles ≥ 4.0 units)."""
import numpy as np
import pytest

from backend.lights.point import PointLight

from lights_util import (K_SIGMA, bsdf_irradiance, check_mis_consistency, chi2_directions,
                         nee_irradiance, translate)

P = 40.0
COLOR = np.array([1.0, 0.5, 0.25])


def test_point_light_irradiance_is_inverse_square():
    light = PointLight(translate(0.2, -0.1, 2.0), P, COLOR)
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(-3, 3, 50), rng.uniform(-3, 3, 50), np.zeros(50)])
    s = light.sample(pts, rng.random((50, 2)))
    v = np.array([0.2, -0.1, 2.0]) - pts
    r2 = (v * v).sum(axis=1)
    cos = v[:, 2] / np.sqrt(r2)
    expected = COLOR * P / (4 * np.pi) * (cos / r2)[:, None]          # E = I cos θ / r²
    assert np.allclose(s.value * s.wi[:, 2:3], expected, rtol=1e-12)
    assert np.all(s.pdf == 0) and light.is_delta and not light.is_hittable


def test_point_light_flux_equals_power():
    """∮ I dω = 4π I = P: irradiance on a sphere around the light integrates to P."""
    light = PointLight(translate(1, 2, 3), P, [1, 1, 1])
    dirs = np.random.default_rng(2).normal(size=(1000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    R = 5.0
    pts = np.array([1, 2, 3]) + R * dirs
    s = light.sample(pts, np.zeros((1000, 2)))
    e = (s.value[:, 0] * np.einsum("ij,ij->i", s.wi, -dirs))
    assert np.allclose(e * 4 * np.pi * R * R, P, rtol=1e-12)


@pytest.mark.parametrize("soft", [False, True])
def test_sphere_and_soft_disk_irradiance_closed_form(soft):
    """Fully visible cap: E = π L sin²α cos θ, L = P/(4π² r²); sin²α = r²/d² for the sphere,
    r²/(r² + d²) for the soft-falloff disk that faces the point."""
    r = 0.3
    c = np.array([0.0, 0.0, 1.5])
    light = PointLight(translate(*c), P, COLOR, radius=r, soft_falloff=soft)
    L = COLOR * P / (4 * np.pi ** 2 * r * r)
    rng = np.random.default_rng(3)
    for p, tilt in (([0.0, 0.0, 0.0], 0.0), ([0.8, -0.4, 0.2], 25.0), ([0.2, 0.3, 0.9], 40.0)):
        p = np.array(p)
        v = c - p
        d = np.linalg.norm(v)
        a = np.radians(tilt)
        axis = v / d
        # a normal tilted by `tilt` from the direction to the centre
        perp = np.cross(axis, [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp)
        normal = np.cos(a) * axis + np.sin(a) * perp
        sin2 = r * r / (r * r + d * d) if soft else r * r / (d * d)
        assert np.arcsin(np.sqrt(sin2)) + a < np.pi / 2   # cap fully above the horizon
        expected = np.pi * L * sin2 * np.cos(a)
        mean, se, _ = nee_irradiance(light, p, normal, 40000, rng)
        assert np.all(np.abs(mean - expected) <= K_SIGMA * se + 1e-12), (mean, expected, se)
        # BSDF-style estimate (cosine rays hitting the emitter) agrees as well
        mean_b, se_b = bsdf_irradiance(light, p, normal, 40000, rng)
        assert np.all(np.abs(mean_b - expected) <= K_SIGMA * se_b), (mean_b, expected, se_b)


def test_sphere_light_flux_equals_power():
    """Irradiance integrated over an enclosing sphere of radius R equals P (Monte Carlo)."""
    r, R = 0.5, 2.0
    light = PointLight(translate(0, 0, 0), P, [1, 1, 1], radius=r)
    rng = np.random.default_rng(4)
    n = 40000
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    s = light.sample(R * dirs, rng.random((n, 2)))
    flux = s.value[:, 0] * np.maximum(np.einsum("ij,ij->i", s.wi, -dirs), 0) * 4 * np.pi * R * R
    assert abs(flux.mean() - P) <= K_SIGMA * flux.std() / np.sqrt(n)


def test_inside_sphere_light_sees_uniform_radiance():
    """Inside the sphere every direction sees L: E = π L for any surface orientation."""
    r = 1.0
    light = PointLight(translate(0, 0, 0), P, COLOR, radius=r)
    L = COLOR * P / (4 * np.pi ** 2 * r * r)
    rng = np.random.default_rng(5)
    for p, n in (([0.0, 0.0, 0.0], [0, 0, 1]), ([0.5, 0.2, -0.3], [0.6, 0.0, 0.8])):
        mean, se, s = nee_irradiance(light, p, n, 40000, rng)
        assert np.all(np.abs(mean - np.pi * L) <= K_SIGMA * se), (mean, se)
        assert np.all(s.dist > 0) and np.all(np.isfinite(s.dist))
        mean_b, se_b = bsdf_irradiance(light, p, n, 20000, rng)
        assert np.allclose(mean_b, np.pi * L, rtol=1e-12)   # every cosine ray hits: no noise


@pytest.mark.parametrize("soft, where", [(False, [0.3, 0.1, -1.2]), (False, [0.0, 0.0, 0.2]),
                                         (True, [0.3, 0.1, -1.2])])
def test_sphere_sampling_matches_pdf_hit(soft, where):
    r = 0.4
    light = PointLight(translate(0.1, 0, 0.3), P, [1, 1, 1], radius=r, soft_falloff=soft)
    o = np.array(where)
    rng = np.random.default_rng(6)
    check_mis_consistency(light, o, 2000, rng)
    axis = light.position - o
    d = np.linalg.norm(axis)
    if d > r:
        sin2 = r * r / (d * d + (r * r if soft else 0.0))
        cos_min = np.sqrt(1 - sin2)
    else:
        cos_min = -1.0
    p_value, outside, mass = chi2_directions(light, o, axis, cos_min, 100000, rng)
    assert outside == 0
    assert abs(mass - 1.0) < 2e-3
    assert p_value > 0.01, p_value


def test_degenerate_inputs_give_zero_not_nan():
    light = PointLight(translate(0, 0, 1), P, [1, 1, 1])
    s = light.sample(np.array([[0.0, 0.0, 1.0]]), np.zeros((1, 2)))
    assert np.all(np.isfinite(s.value)) and np.all(s.value == 0)
    sphere = PointLight(translate(0, 0, 1), P, [1, 1, 1], radius=0.5)
    s = sphere.sample(np.array([[0.0, 0.0, 1.0]]), np.full((1, 2), 0.5))
    assert np.all(np.isfinite(s.value)) and np.all(np.isfinite(s.wi))
