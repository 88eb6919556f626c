"""Reciprocity, energy conservation over a parameter sweep, and the microfacet energy loss of a
perfectly reflecting conductor against an independent quadrature."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import special, stats

from backend.materials.base import IMPORTANCE, RADIANCE, ShadingContext
from backend.materials.conductor import ConductorBSDF, ConductorMaterial
from backend.materials.dielectric import DielectricBSDF, DielectricMaterial
from backend.materials.diffuse import DiffuseMaterial
from stats_util import SIGNIFICANCE, Grid, mean_and_stderr, sidak

CTX = ShadingContext(np.zeros((1, 2)))


def random_dirs(rng, n):
    w = rng.normal(size=(n, 3))
    return w / np.linalg.norm(w, axis=1, keepdims=True)


def direction(theta_deg, phi=0.0):
    t = math.radians(theta_deg)
    return np.array([math.sin(t) * math.cos(phi), math.sin(t) * math.sin(phi), math.cos(t)])


# ---------------------------------------------------------------------------------- reciprocity
REFLECTORS = {
    "diffuse": lambda: DiffuseMaterial([0.3, 0.6, 0.9]),
    "ggx-aniso": lambda: ConductorMaterial.named("Au", roughness=0.4, roughness_v=0.1),
    "beckmann-aniso": lambda: ConductorMaterial.named("Cu", roughness=0.1, roughness_v=0.5,
                                                      distribution="beckmann"),
    "beckmann-separable": lambda: ConductorMaterial.named("Al", roughness=0.3,
                                                          distribution="beckmann",
                                                          masking="separable"),
    "ggx-coated": lambda: ConductorMaterial.named("Ag", roughness=0.2, eta_above=1.5),
}


@pytest.mark.parametrize("name", sorted(REFLECTORS))
def test_reflection_is_reciprocal(name):
    bsdf = REFLECTORS[name]().bind(CTX)
    rng = np.random.default_rng(21)
    wi, wo = random_dirs(rng, 20_000), random_dirs(rng, 20_000)
    keep = (np.abs(wi[:, 2]) > 1e-3) & (np.abs(wo[:, 2]) > 1e-3)
    wi, wo = wi[keep], wo[keep]
    f_io = bsdf.eval(wi, wo, rng) / np.abs(wo[:, 2:3])
    f_oi = bsdf.eval(wo, wi, rng) / np.abs(wi[:, 2:3])
    assert (f_io > 0).any(axis=1).mean() > 0.3     # not a vacuous comparison
    np.testing.assert_allclose(f_io, f_oi, rtol=1e-7, atol=1e-300)


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
@pytest.mark.parametrize("masking", ["height-correlated", "separable"])
@pytest.mark.parametrize("ior,ior_above", [(1.5, 1.0), (1.1, 1.4)])
def test_dielectric_reciprocity_and_eta_squared_rule(dist, masking, ior, ior_above):
    mat = DielectricMaterial(ior=ior, ior_above=ior_above, roughness=0.5, roughness_v=0.2,
                             distribution=dist, masking=masking)
    bsdf = mat.bind(CTX)
    rng = np.random.default_rng(22)
    wi, wo = random_dirs(rng, 40_000), random_dirs(rng, 40_000)
    keep = (np.abs(wi[:, 2]) > 1e-3) & (np.abs(wo[:, 2]) > 1e-3)
    wi, wo = wi[keep], wo[keep]
    index = lambda w: np.where(w[:, 2] > 0, ior_above, ior)[:, None]  # noqa: E731
    f_io = bsdf.eval(wi, wo, rng, RADIANCE) / np.abs(wo[:, 2:3])
    f_oi = bsdf.eval(wo, wi, rng, RADIANCE) / np.abs(wi[:, 2:3])
    trans = wi[:, 2] * wo[:, 2] < 0
    assert (f_io[trans] > 0).any(axis=1).mean() > 0.1
    assert (f_io[~trans] > 0).any(axis=1).mean() > 0.2
    # Reflection: symmetric. Transmission (radiance): f(wi, wo) / n(wi)² is symmetric
    # (Veach 1997, eq. 5.14 — radiance BTDFs are not reciprocal, f/n² is).
    # Tolerance: float64 round-off, amplified where 1 − F cancels near the critical angle.
    atol = 1e-10 * f_io.max()
    np.testing.assert_allclose(f_io / index(wi) ** 2, f_oi / index(wo) ** 2, rtol=1e-7, atol=atol)
    # Importance mode is the adjoint: f_importance(wi, wo) = f_radiance(wo, wi).
    f_imp = bsdf.eval(wi, wo, rng, IMPORTANCE) / np.abs(wo[:, 2:3])
    np.testing.assert_allclose(f_imp, f_oi, rtol=1e-7, atol=atol)


# ---------------------------------------------------------------------------------- energy sweep
ALPHAS = np.array([1e-4, 1e-3, 1e-2, 0.1, 0.3, 0.6, 1.0])
IORS = np.array([1.0001, 1.2, 1.5, 2.0, 3.0])
THETAS = np.array([0.0, 30.0, 60.0, 80.0, 89.0])
M = 2000   # samples per configuration: half from the BSDF, half uniform on the sphere


def defensive_albedo(bsdf, wi, configs, mode):
    """Per configuration (lanes grouped in runs of M): ∫ f |cos| dωo estimated as
    eval / (½ pdf + ½ /4π), half the directions drawn by sample(), half uniformly (an unbiased
    estimate of what eval integrates to, even if sample()/pdf() were wrong), plus the mean
    sample weight (what sample() integrates to). Returns means and standard errors (n, 2)."""
    rng = np.random.default_rng(31)
    n = wi.shape[0]
    s = bsdf.sample(wi, rng, mode)
    wo = s.wo.copy()
    uni = (np.arange(n) % M) >= M // 2
    wo[uni] = random_dirs(rng, int(uni.sum()))
    q = 0.5 * bsdf.pdf(wi, wo, rng, mode) + 0.5 / (4.0 * np.pi)
    est = bsdf.eval(wi, wo, rng, mode)[:, 0] / q
    # A failed sample() is the "no direction" outcome of that strategy, not a direction drawn
    # with density pdf: it contributes 0 (the mixture density q is still correct).
    est = np.where(~uni & ~(s.pdf > 0), 0.0, est)
    assert np.all(np.isfinite(est)) and np.all(np.isfinite(s.weight))
    e_mean, e_err = mean_and_stderr(est.reshape(configs, M), axis=1)
    w = s.weight[:, 0].reshape(configs, M)[:, : M // 2]
    w_mean, w_err = mean_and_stderr(w, axis=1)
    return e_mean, e_err, w_mean, w_err


def consistency_z(n_tests):
    return stats.norm.isf(sidak(SIGNIFICANCE, n_tests) / 2)


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
def test_dielectric_albedo_sweep(dist):
    """Importance-mode directional albedo (the energy actually scattered) <= 1 + 3σ for
    α 1e-4…1, relative IOR 1.0001…3 (from above; from below the same pairs give 1/η), 10 angles."""
    a, e, t, side = np.meshgrid(ALPHAS, IORS, THETAS, [1.0, -1.0], indexing="ij")
    a, e, t, side = a.ravel(), e.ravel(), t.ravel(), side.ravel()
    configs = a.size
    wi_c = np.stack([np.sin(np.radians(t)), np.zeros(configs), np.cos(np.radians(t)) * side], 1)
    rep = lambda x: np.repeat(x, M, axis=0)  # noqa: E731
    bsdf = DielectricBSDF(configs * M, rep(e), np.ones((1, 3)), rep(a), rep(a), dist)
    e_mean, e_err, w_mean, w_err = defensive_albedo(bsdf, rep(wi_c), configs, IMPORTANCE)
    over = e_mean - (1.0 + 3.0 * e_err)
    worst = int(np.argmax(over))
    assert over.max() <= 0, (f"albedo {e_mean[worst]:.5f} ± {e_err[worst]:.5f} at α={a[worst]}, "
                             f"η={e[worst]}, θ={t[worst]}, side={side[worst]}")
    assert np.all(w_mean <= 1.0 + 3.0 * w_err + 1e-12)
    # eval/pdf and sample() describe the same scattering: both estimates agree.
    z = np.abs(e_mean - w_mean) / np.sqrt(e_err ** 2 + w_err ** 2 + 1e-30)
    assert z.max() < consistency_z(configs), z.max()


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
@pytest.mark.parametrize("masking", ["height-correlated", "separable"])
def test_conductor_albedo_sweep(dist, masking):
    """A conductor with F ≡ 1 (eta 0, k 1) over α 1e-4…1 (incl. anisotropic) and angles."""
    a, t = np.meshgrid(ALPHAS, np.append(THETAS, [45.0, 85.0]), indexing="ij")
    a, t = a.ravel(), t.ravel()
    a = np.concatenate([a, a])
    av = np.concatenate([a[: a.size // 2], np.maximum(a[: a.size // 2] * 0.2, 1e-4)])
    t = np.concatenate([t, t])
    configs = a.size
    wi_c = np.stack([np.sin(np.radians(t)) * 0.6, np.sin(np.radians(t)) * 0.8,
                     np.cos(np.radians(t))], 1)
    rep = lambda x: np.repeat(x, M, axis=0)  # noqa: E731
    bsdf = ConductorBSDF(configs * M, np.zeros((1, 3)), np.ones((1, 3)), np.ones((1, 3)),
                         rep(a), rep(av), dist, masking)
    e_mean, e_err, w_mean, w_err = defensive_albedo(bsdf, rep(wi_c), configs, RADIANCE)
    assert np.all(e_mean <= 1.0 + 3.0 * e_err), (e_mean - 1.0 - 3 * e_err).max()
    assert np.all(w_mean <= 1.0 + 3.0 * w_err + 1e-12)
    z = np.abs(e_mean - w_mean) / np.sqrt(e_err ** 2 + w_err ** 2 + 1e-30)
    assert z.max() < consistency_z(configs), z.max()


def test_diffuse_white_albedo_is_one():
    bsdf = DiffuseMaterial(1.0).bind(CTX)
    rng = np.random.default_rng(3)
    for theta in (0.0, 60.0, 89.9, 150.0):
        s = bsdf.sample(np.tile(direction(theta), (10_000, 1)), rng)
        assert np.all(s.weight == 1.0)
    # ∫ eval dωo = 1 by quadrature (a full-sphere grid; the lower half must give 0).
    wi = direction(40.0)
    total = Grid(20, 32).integrate(lambda w: bsdf.eval(np.broadcast_to(wi, w.shape), w, rng)[:, 0])
    assert total.sum() == pytest.approx(1.0, abs=1e-6)


# ---------------------------------------------------------------------------------- F = 1 conductor
def reference_D(dist, alpha, cos_h):
    c2 = cos_h * cos_h
    if dist == "ggx":
        return alpha ** 2 / (np.pi * (1.0 + (alpha ** 2 - 1.0) * c2) ** 2)
    tan2 = (1.0 - c2) / c2
    return np.exp(-tan2 / alpha ** 2) / (np.pi * alpha ** 2 * c2 * c2)


def reference_lambda(dist, alpha, cos_t):
    tan = np.sqrt(np.maximum(1.0 - cos_t ** 2, 0.0)) / cos_t
    if dist == "ggx":
        return 0.5 * (np.sqrt(1.0 + (alpha * tan) ** 2) - 1.0)
    a = np.minimum(1.0 / np.maximum(alpha * tan, 1e-300), 1e6)   # Λ = 0 to double precision
    return 0.5 * (special.erf(a) - 1.0 + np.exp(-a * a) / (a * np.sqrt(np.pi)))


def reference_G1_rational(a):
    return np.where(a < 1.6, (3.535 * a + 2.181 * a * a) / (1 + 2.276 * a + 2.577 * a * a), 1.0)


def reference_albedo(dist, masking, alpha, wi):
    """E(wi) = ∫ D(h) G2(wi, wo) / (4 cosθi) dωo by adaptive quadrature (F = 1, isotropic)."""
    def integrand(wo):
        ok = wo[:, 2] > 0
        h = wo + wi
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        lo = reference_lambda(dist, alpha, np.maximum(wo[:, 2], 1e-12))
        li = reference_lambda(dist, alpha, np.array([wi[2]]))
        if masking == "height-correlated":
            g = 1.0 / (1.0 + li + lo)
        elif dist == "ggx":
            g = 1.0 / ((1.0 + li) * (1.0 + lo))
        else:
            tan = lambda c: np.sqrt(np.maximum(1 - c * c, 0)) / c  # noqa: E731
            ai = 1.0 / max(alpha * tan(wi[2]), 1e-300)
            ao = 1.0 / np.maximum(alpha * tan(np.maximum(wo[:, 2], 1e-12)), 1e-300)
            g = reference_G1_rational(ai) * reference_G1_rational(ao)
        val = reference_D(dist, alpha, h[:, 2]) * g / (4.0 * wi[2])
        return np.where(ok, val, 0.0)
    return Grid(16, 32, 0.0, 1.0).integrate(integrand, tol=1e-9).sum()


@pytest.mark.parametrize("dist,masking", [("ggx", "height-correlated"), ("ggx", "separable"),
                                          ("beckmann", "height-correlated"),
                                          ("beckmann", "separable")])
@pytest.mark.parametrize("alpha", [0.1, 0.5, 1.0])
def test_perfect_conductor_albedo_is_one_minus_microfacet_loss(dist, masking, alpha):
    mat = ConductorMaterial(eta=0.0, k=1.0, roughness=alpha, distribution=dist, masking=masking)
    bsdf = mat.bind(CTX)
    rng = np.random.default_rng(41)
    for theta in (0.0, 60.0, 85.0):
        wi = direction(theta, 0.3)
        ref = reference_albedo(dist, masking, alpha, wi)
        s = bsdf.sample(np.tile(wi, (40_000, 1)), rng)
        mean, err = mean_and_stderr(s.weight[:, 0])
        assert abs(mean - ref) < 4 * err + 1e-5, (theta, mean, err, ref)
        assert ref < 1.0


def test_smooth_perfect_conductor_albedo_is_exactly_one():
    bsdf = ConductorMaterial(eta=0.0, k=1.0, roughness=0.0).bind(CTX)
    rng = np.random.default_rng(1)
    for theta in (0.0, 45.0, 89.0, 89.999):
        s = bsdf.sample(np.tile(direction(theta), (100, 1)), rng)
        assert np.all(s.weight == 1.0) and s.delta.all()
