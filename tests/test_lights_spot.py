"""Spot lights against a direct evaluation of Cycles' cone falloff written here."""
import numpy as np
import pytest

from backend.lights.spot import SpotLight

from lights_util import (K_SIGMA, bsdf_irradiance, check_mis_consistency, chi2_directions,
                         frame, nee_irradiance, rot_x, translate)

P = 100.0


def cycles_spot_factor(to_world, w_out, spot_size, blend):
    """Cycles (kernel/light/spot.h): the travel direction in the light's local space (inverse
    object matrix, normalised, z negated), then smoothstep((z − cos(size/2)) · spot_smooth)."""
    inv = np.linalg.inv(to_world[:3, :3])
    loc = w_out @ inv.T
    loc /= np.linalg.norm(loc, axis=1, keepdims=True)
    z = -loc[:, 2]
    cos_half = np.cos(spot_size / 2)
    if blend == 0:
        return (z > cos_half).astype(float)
    x = np.clip((z - cos_half) / ((1 - cos_half) * blend), 0, 1)
    return (3 - 2 * x) * x * x


@pytest.mark.parametrize("linear, blend", [(np.eye(3), 0.15), (rot_x(30) @ np.diag([2.0, 0.7, 1.0]), 0.4),
                                           (rot_x(-20), 0.0)])
def test_delta_spot_irradiance_on_a_plane(linear, blend):
    size = np.radians(50.0)
    m = translate(0.3, -0.2, 2.0, linear)
    light = SpotLight(m, P, [1, 0.8, 0.6], size, blend)
    g = np.linspace(-2.5, 2.5, 41)
    X, Y = np.meshgrid(g, g)
    pts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    s = light.sample(pts, np.zeros((pts.shape[0], 2)))
    v = m[:3, 3] - pts
    r2 = (v * v).sum(axis=1)
    w_out = -v / np.sqrt(r2)[:, None]
    f = cycles_spot_factor(m, w_out, size, blend)
    expected = (P / (4 * np.pi)) * f * (v[:, 2] / np.sqrt(r2)) / r2
    got = s.value[:, 0] * s.wi[:, 2]
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-14)
    ramp = int(((f > 0) & (f < 1)).sum())
    assert (f > 0).any() and (f == 0).any() and (ramp == 0 if blend == 0 else ramp > 10)
    assert np.all(s.value[f == 0] == 0)   # outside the cone: no contribution, no shadow ray


@pytest.mark.parametrize("blend", [0.0, 0.3, 1.0])
def test_spot_flux_and_power(blend):
    """∮ I dω = P/(4π) · 2π ∫ smoothstep dz = P (1 − cos(size/2))(1 − blend/2)/2 (uniform scale)."""
    size = np.radians(70.0)
    light = SpotLight(translate(0, 0, 0, rot_x(10)), P, [1, 1, 1], size, blend)
    n = 400000
    dirs = np.random.default_rng(7).normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    s = light.sample(3.0 * dirs, np.zeros((n, 2)))
    intensity = s.value[:, 0] * 9.0
    flux = intensity * 4 * np.pi
    expected = P * (1 - np.cos(size / 2)) * (1 - blend / 2) / 2
    assert abs(flux.mean() - expected) <= K_SIGMA * flux.std() / np.sqrt(n)
    assert light.power() == pytest.approx(expected, rel=1e-6)


def test_sphere_spot_irradiance_matches_quadrature_and_mis():
    """Sphere spot light close by (its cone narrower than the sphere's: the spot cone is sampled):
    NEE and BSDF-style estimates vs quadrature of L · falloff(−ω) · cos over the visible cap."""
    r = 0.5
    size, blend = np.radians(40.0), 0.5
    m = translate(0, 0, 1.2, rot_x(15))
    light = SpotLight(m, P, [1, 1, 1], size, blend, radius=r)
    L = P / (4 * np.pi ** 2 * r * r)
    rng = np.random.default_rng(8)
    for p, normal in (([0.0, 0.0, 0.0], [0, 0, 1]), ([0.25, 0.4, 0.2], [0.3, 0, 0.95])):
        p = np.array(p, float)
        normal = np.array(normal, float) / np.linalg.norm(normal)
        c = m[:3, 3]
        d = np.linalg.norm(c - p)
        cos_a = np.sqrt(1 - r * r / (d * d))
        # quadrature over the cap (cos θ ∈ [cos α, 1], φ), midpoint rule
        s, t, n = frame(c - p)
        k = 600
        cc = cos_a + (np.arange(k) + 0.5) * (1 - cos_a) / k
        ph = (np.arange(k) + 0.5) * 2 * np.pi / k
        C, PH = np.meshgrid(cc, ph, indexing="ij")
        sn = np.sqrt(1 - C * C)
        w = ((sn * np.cos(PH))[..., None] * s + (sn * np.sin(PH))[..., None] * t + C[..., None] * n).reshape(-1, 3)
        f = cycles_spot_factor(m, -w, size, blend)
        e_ref = np.sum(L * f * np.maximum(w @ normal, 0)) * (1 - cos_a) / k * 2 * np.pi / k
        mean, se, smp = nee_irradiance(light, p, normal, 100000, rng)
        assert abs(mean[0] - e_ref) <= K_SIGMA * se[0] + 1e-4 * e_ref, (mean, e_ref, se)
        mean_b, se_b = bsdf_irradiance(light, p, normal, 100000, rng)
        assert abs(mean_b[0] - e_ref) <= K_SIGMA * se_b[0] + 1e-4 * e_ref, (mean_b, e_ref, se_b)
        check_mis_consistency(light, p, 4000, rng)


def test_sphere_spot_spread_cone_sampling_chi2():
    r = 0.5
    size = np.radians(30.0)
    m = translate(0, 0, 1.0)
    light = SpotLight(m, P, [1, 1, 1], size, 0.2, radius=r)
    o = np.array([0.05, 0.0, 0.2])
    cos_wide = np.cos(size / 2)
    assert np.sqrt(1 - r * r / np.sum((m[:3, 3] - o) ** 2)) < cos_wide   # spot cone is narrower
    rng = np.random.default_rng(9)
    p_value, outside, mass = chi2_directions(light, o, [0, 0, 1], cos_wide, 100000, rng)
    assert outside == 0 and p_value > 0.01, (p_value, outside)
