"""Every BSDF sampling routine against its pdf (chi-square), sample weight = eval/pdf, sample pdf =
pdf(), and the delta lobes (mirror, smooth dielectric) against closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from backend.materials.base import IMPORTANCE, RADIANCE, ShadingContext
from backend.materials.conductor import ConductorMaterial
from backend.materials.dielectric import DielectricMaterial
from backend.materials.diffuse import DiffuseMaterial
from backend.materials.fresnel import conductor as fresnel_conductor, dielectric as fresnel_dielectric
from stats_util import SIGNIFICANCE, Grid, chi2_test, sidak

LEVEL = sidak(SIGNIFICANCE, 80)   # shared family with test_materials_microfacet.py
N = 100_000
SPHERE = Grid(20, 32, -1.0, 1.0)
CTX = ShadingContext(np.zeros((1, 2)))   # constant parameters broadcast over any lane count


def direction(theta_deg, phi=0.0):
    t = math.radians(theta_deg)
    return np.array([math.sin(t) * math.cos(phi), math.sin(t) * math.sin(phi), math.cos(t)])


def check_sampler(bsdf, wi_dir, mode=RADIANCE, seed=1):
    rng = np.random.default_rng(seed)
    wi = np.tile(wi_dir, (N, 1))
    s = bsdf.sample(wi, rng, mode)
    for a in s:
        assert np.all(np.isfinite(a))
    assert not s.delta.any()
    ok = s.pdf > 0
    # Failed samples carry no weight; successful ones are unit directions.
    assert np.all(s.weight[~ok] == 0)
    assert np.allclose(np.linalg.norm(s.wo[ok], axis=1), 1.0)
    wo = s.wo[ok]
    ev = bsdf.eval(wi[ok], wo, rng, mode)
    pd = bsdf.pdf(wi[ok], wo, rng, mode)
    # The pdf reported by sample() is pdf(), and the weight is eval/pdf (analytic BSDFs).
    np.testing.assert_allclose(s.pdf[ok], pd, rtol=1e-8)
    np.testing.assert_allclose(s.weight[ok], ev / pd[:, None], rtol=1e-7, atol=1e-12)
    res = chi2_test(wo, N, lambda w: bsdf.pdf(np.broadcast_to(wi_dir, w.shape), w, rng, mode),
                    SPHERE)
    assert res.p_value > LEVEL, str(res)
    # ∫pdf = fraction of samples that produced a direction (the rest fell below the horizon).
    sigma = math.sqrt(max(res.success_fraction * (1 - res.success_fraction), 1.0 / N) / N)
    assert abs(res.integral - res.success_fraction) < 4 * sigma + 1e-4, str(res)
    return res


# ---------------------------------------------------------------------------------- diffuse
@pytest.mark.parametrize("theta", [0.0, 45.0, 89.0, 120.0])
def test_diffuse_sampling(theta):
    bsdf = DiffuseMaterial([0.5, 0.6, 0.7]).bind(CTX)
    res = check_sampler(bsdf, direction(theta, 0.3))
    assert res.integral == pytest.approx(1.0, abs=1e-4)


# ---------------------------------------------------------------------------------- conductor
CONDUCTOR_CASES = [
    # distribution, αu, αv, θi, φi, masking
    (d, au, av, th, ph, mk) for d in ("ggx", "beckmann") for (au, av, th, ph, mk) in (
        (0.3, 0.3, 0.0, 0.0, "height-correlated"),
        (0.3, 0.3, 60.0, 0.2, "height-correlated"),
        (0.3, 0.3, 89.0, 1.0, "height-correlated"),
        (0.1, 0.1, 45.0, 0.0, "height-correlated"),
        (0.5, 0.08, 30.0, 0.5, "height-correlated"),
        (0.08, 0.5, 85.0, 1.2, "height-correlated"),
        (1.0, 1.0, 80.0, 2.0, "height-correlated"),
        (0.4, 0.2, 70.0, 0.7, "separable"),
    )]


@pytest.mark.parametrize("dist,au,av,theta,phi,masking", CONDUCTOR_CASES)
def test_rough_conductor_sampling(dist, au, av, theta, phi, masking):
    mat = ConductorMaterial.named("Au", roughness=au, roughness_v=av, distribution=dist,
                                  masking=masking)
    check_sampler(mat.bind(CTX), direction(theta, phi))


def test_conductor_from_below_is_mirrored():
    """Two-sided: wi below the surface behaves as its mirror image above."""
    bsdf = ConductorMaterial.named("Cu", roughness=0.3, roughness_v=0.1).bind(CTX)
    rng = np.random.default_rng(5)
    wi = np.tile(direction(50.0, 0.4), (1000, 1))
    wo = rng.normal(size=(1000, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    flip = np.array([1.0, 1.0, -1.0])
    np.testing.assert_allclose(bsdf.eval(wi * flip, wo * flip, rng), bsdf.eval(wi, wo, rng))
    np.testing.assert_allclose(bsdf.pdf(wi * flip, wo * flip, rng), bsdf.pdf(wi, wo, rng))
    s = bsdf.sample(wi * flip, rng)
    assert np.all(s.wo[s.pdf > 0, 2] < 0)


def test_smooth_conductor_is_a_delta_mirror():
    eta, k = np.array([0.2, 0.9, 1.1]), np.array([3.9, 2.4, 2.1])
    bsdf = ConductorMaterial(eta, k, roughness=0.0, tint=[1.0, 0.5, 0.25]).bind(CTX)
    assert bsdf.delta_only
    rng = np.random.default_rng(2)
    for theta in (0.0, 30.0, 75.0, 89.9):
        wi = np.tile(direction(theta, 0.8), (16, 1))
        s = bsdf.sample(wi, rng)
        assert s.delta.all() and np.all(s.pdf == 0)
        np.testing.assert_allclose(s.wo, wi * np.array([-1.0, -1.0, 1.0]))
        f = fresnel_conductor(np.full((16, 1), wi[0, 2]), eta, k) * np.array([1.0, 0.5, 0.25])
        np.testing.assert_allclose(s.weight, f, rtol=1e-12)
        assert np.all(bsdf.eval(wi, s.wo, rng) == 0) and np.all(bsdf.pdf(wi, s.wo, rng) == 0)


# ---------------------------------------------------------------------------------- dielectric
DIELECTRIC_CASES = [
    # distribution, ior, αu, αv, θi (> 90: arriving from below), φi
    (d, ior, au, av, th, ph) for d in ("ggx", "beckmann") for (ior, au, av, th, ph) in (
        (1.5, 0.3, 0.3, 0.0, 0.0),
        (1.5, 0.3, 0.3, 50.0, 0.3),
        (1.5, 0.3, 0.3, 87.0, 1.0),
        (1.5, 0.4, 0.1, 70.0, 0.6),
        (1.5, 0.3, 0.3, 180.0, 0.0),      # from below, normal incidence
        (1.5, 0.3, 0.3, 150.0, 0.2),      # from below, inside the critical angle
        (1.5, 0.2, 0.2, 130.0, 0.9),      # from below, beyond the critical angle (41.8°)
        (1.5, 0.1, 0.5, 95.0, 2.0),       # from below, grazing, anisotropic
        (1.33, 0.6, 0.6, 40.0, 0.0),
        (0.7, 0.3, 0.3, 60.0, 0.4),       # denser medium above
    )]


@pytest.mark.parametrize("dist,ior,au,av,theta,phi", DIELECTRIC_CASES)
def test_rough_dielectric_sampling(dist, ior, au, av, theta, phi):
    mat = DielectricMaterial(ior=ior, roughness=au, roughness_v=av, distribution=dist,
                             transmission_color=[0.9, 0.7, 0.5])
    bsdf = mat.bind(CTX)
    wi = direction(theta, phi)
    res = check_sampler(bsdf, wi, RADIANCE)
    # Importance mode samples the same directions with the same pdf; only weights change.
    rng = np.random.default_rng(1)
    s_rad = bsdf.sample(np.tile(wi, (2000, 1)), np.random.default_rng(9), RADIANCE)
    s_imp = bsdf.sample(np.tile(wi, (2000, 1)), np.random.default_rng(9), IMPORTANCE)
    np.testing.assert_array_equal(s_rad.wo, s_imp.wo)
    ok = s_imp.pdf > 0
    ev = bsdf.eval(np.tile(wi, (int(ok.sum()), 1)), s_imp.wo[ok], rng, IMPORTANCE)
    np.testing.assert_allclose(s_imp.weight[ok], ev / s_imp.pdf[ok, None], rtol=1e-7, atol=1e-12)
    assert res.success_fraction > 0.5


@pytest.mark.parametrize("ior,ior_above", [(1.5, 1.0), (1.0, 1.5), (2.4, 1.33)])
@pytest.mark.parametrize("theta", [0.0, 35.0, 80.0, 180.0, 160.0, 120.0, 95.0])
def test_smooth_dielectric_delta_lobes(ior, ior_above, theta):
    n_s = 200_000
    tint = np.array([0.9, 0.8, 0.3])
    bsdf = DielectricMaterial(ior=ior, ior_above=ior_above, roughness=0.0,
                              transmission_color=tint).bind(CTX)
    assert bsdf.delta_only
    wi_dir = direction(theta, 0.7)
    wi = np.tile(wi_dir, (n_s, 1))
    s = bsdf.sample(wi, np.random.default_rng(4), RADIANCE)
    assert s.delta.all() and np.all(s.pdf == 0)
    refl = s.wo[:, 2] * wi_dir[2] > 0
    # Closed forms: Snell's law and the Fresnel equations written out here.
    n_i, n_t = (ior_above, ior) if wi_dir[2] > 0 else (ior, ior_above)
    ci = abs(wi_dir[2])
    st = n_i / n_t * math.sqrt(1 - ci * ci)
    if st >= 1:
        F = 1.0
    else:
        ct = math.sqrt(1 - st * st)
        rs = (n_i * ci - n_t * ct) / (n_i * ci + n_t * ct)
        rp = (n_t * ci - n_i * ct) / (n_t * ci + n_i * ct)
        F = 0.5 * (rs * rs + rp * rp)
    assert F == pytest.approx(float(fresnel_dielectric(wi_dir[2], ior / ior_above)[0]), abs=1e-12)
    # The choice of lobe is Bernoulli(F): two-cell chi-square.
    k = refl.sum()
    if 0 < F < 1:
        stat = (k - n_s * F) ** 2 / (n_s * F * (1 - F))
        from scipy.stats import chi2
        assert chi2.sf(stat, 1) > LEVEL
    else:
        assert k == (n_s if F == 1 else 0)
    np.testing.assert_allclose(s.wo[refl], np.tile(wi_dir * [-1, -1, 1], (k, 1)), atol=1e-15)
    np.testing.assert_allclose(s.weight[refl], 1.0)
    if k < n_s:
        wo_t = s.wo[~refl]
        np.testing.assert_allclose(np.linalg.norm(wo_t, axis=1), 1.0)
        # Snell: n_i sinθi = n_t sinθt, opposite azimuth, other side.
        np.testing.assert_allclose(np.hypot(wo_t[:, 0], wo_t[:, 1]) * n_t,
                                   math.sqrt(1 - ci * ci) * n_i, atol=1e-12)
        assert np.all(wo_t[:, 2] * wi_dir[2] < 0)
        np.testing.assert_allclose(wo_t[:, :2] * n_t, -np.tile(wi_dir[:2] * n_i, (len(wo_t), 1)),
                                   atol=1e-12)
        # Radiance: (1/η²) tint with η = n_t/n_i; importance: tint.
        np.testing.assert_allclose(s.weight[~refl], np.tile(tint * (n_i / n_t) ** 2, (len(wo_t), 1)))
        s_imp = bsdf.sample(wi[:100], np.random.default_rng(4), IMPORTANCE)
        t_imp = s_imp.wo[:, 2] * wi_dir[2] < 0
        np.testing.assert_allclose(s_imp.weight[t_imp], np.tile(tint, (int(t_imp.sum()), 1)))


def test_chi2_detects_a_wrong_pdf():
    """Power check of the test itself: a 10 % roughness mismatch must be rejected."""
    sampler = ConductorMaterial.named("Ag", roughness=0.3).bind(CTX)
    wrong = ConductorMaterial.named("Ag", roughness=0.33).bind(CTX)
    rng = np.random.default_rng(8)
    wi = direction(40.0)
    s = sampler.sample(np.tile(wi, (N, 1)), rng)
    ok = s.pdf > 0
    res = chi2_test(s.wo[ok], N, lambda w: wrong.pdf(np.broadcast_to(wi, w.shape), w, rng), SPHERE)
    assert res.p_value < LEVEL


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
@pytest.mark.parametrize("masking", ["height-correlated", "separable"])
def test_extreme_roughness_and_grazing_angles_stay_finite(dist, masking):
    """α from 1e-4 and |cosθ| down to 1e-6 (and exactly 0): no NaN/Inf in any query."""
    rng = np.random.default_rng(12)
    mats = [ConductorMaterial.named("Cr", roughness=a, roughness_v=a * 3, distribution=dist,
                                    masking=masking) for a in (1e-4, 3e-4, 1e-2, 1.0)]
    mats += [DielectricMaterial(ior=ior, roughness=a, distribution=dist, masking=masking)
             for a in (1e-4, 1e-2, 1.0) for ior in (1.0001, 1.5, 3.0)]
    mats += [DiffuseMaterial(1.0)]
    cz = np.array([1e-6, -1e-6, 0.0, 1e-3, -1.0, 1.0, 1e-12])
    wi = np.stack([np.sqrt(1 - cz ** 2), np.zeros_like(cz), cz], 1)
    wi = np.repeat(wi, 50, axis=0)
    wo = np.concatenate([random_dirs(rng, wi.shape[0] - 7), wi[::50] * [-1, -1, 1]])
    for m in mats:
        b = m.bind(CTX)
        for mode in (RADIANCE, IMPORTANCE):
            for v in (b.eval(wi, wo, rng, mode), b.pdf(wi, wo, rng, mode), *b.sample(wi, rng, mode)):
                assert np.all(np.isfinite(v)), m.__dict__
            assert np.all(b.eval(wi, wo, rng, mode) >= 0) and np.all(b.pdf(wi, wo, rng, mode) >= 0)


def random_dirs(rng, n):
    w = rng.normal(size=(n, 3))
    return w / np.linalg.norm(w, axis=1, keepdims=True)
