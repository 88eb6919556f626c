"""Microfacet distributions: normalisation, Smith Λ, NDF and visible-normal samplers (chi-square),
robustness at α = 1e-4 and grazing cosines."""
from __future__ import annotations

import math

import numpy as np
import pytest

from backend.materials.microfacet import Microfacet
from backend.materials.specfun import erf, erfc, erfinv_from_uniform
from stats_util import SIGNIFICANCE, Grid, chi2_test, sidak, spherical_directions

# All chi-square tests of the materials suite share one family-wise level (upper bound on their
# number; see also test_materials_sampling.py).
LEVEL = sidak(SIGNIFICANCE, 80)
N = 100_000
HEMI = Grid(16, 32, 0.0, 1.0)


def direction(theta_deg, phi=0.0):
    t = math.radians(theta_deg)
    return np.array([math.sin(t) * math.cos(phi), math.sin(t) * math.sin(phi), math.cos(t)])


def test_erfc_matches_math_erfc():
    x = np.linspace(-5.0, 9.0, 3001)
    ref = np.array([math.erfc(v) for v in x])
    # Numerical Recipes' stated bound for erfcc: fractional error < 1.2e-7.
    assert np.max(np.abs(erfc(x) - ref) / ref) < 1.2e-7
    assert np.max(np.abs(erf(x) - np.array([math.erf(v) for v in x]))) < 2.5e-7


def test_erfinv_inverts_erf():
    u = np.concatenate([np.linspace(1e-12, 1 - 1e-12, 2001), [0.5, 1e-300]])
    y = erfinv_from_uniform(u)
    assert np.all(np.isfinite(y))
    back = np.array([math.erf(v) for v in y])
    assert np.max(np.abs(back - (2 * u - 1))) < 5e-7


NDF_CASES = [(d, au, av) for d in ("ggx", "beckmann")
             for au, av in ((0.2, 0.2), (0.5, 0.1), (1.0, 1.0))]


@pytest.mark.parametrize("dist,au,av", NDF_CASES)
def test_ndf_sampler_chi2(dist, au, av):
    mf = Microfacet(dist, au, av)
    rng = np.random.default_rng(7)
    m = mf.sample_ndf(rng.random((N, 2)))
    res = chi2_test(m, N, mf.pdf_ndf, HEMI)
    assert res.p_value > LEVEL, str(res)
    # ∫ D(m) cosθm dm = 1 (projected-area normalisation of D), checked by quadrature.
    assert abs(res.integral - 1.0) < 2e-3 + 10 * res.quad_error, str(res)


VNDF_CASES = [(d, au, av, th, ph) for d in ("ggx", "beckmann")
              for au, av, th, ph in ((0.3, 0.3, 0.0, 0.0), (0.3, 0.3, 60.0, 0.3), (0.3, 0.3, 88.0, 1.0),
                                     (0.6, 0.1, 30.0, 0.7), (0.6, 0.1, 85.0, 0.4),
                                     (0.1, 0.6, 89.0, 2.0), (1.0, 1.0, 75.0, 0.0))]


@pytest.mark.parametrize("dist,au,av,theta,phi", VNDF_CASES)
def test_visible_normal_sampler_chi2(dist, au, av, theta, phi):
    mf = Microfacet(dist, au, av)
    rng = np.random.default_rng(11)
    wi = np.tile(direction(theta, phi), (N, 1))
    m = mf.sample_visible(wi, rng.random((N, 2)))
    assert np.all(np.isfinite(m))
    pdf = lambda w: mf.pdf_visible(np.broadcast_to(wi[:1], w.shape), w)  # noqa: E731
    res = chi2_test(m, N, pdf, HEMI)
    assert res.p_value > LEVEL, str(res)
    # ∫ G1(wi, m) max(0, wi·m) D(m) dm = cosθi: the Smith Λ is consistent with D.
    assert abs(res.integral - 1.0) < 2e-3 + 10 * res.quad_error, str(res)


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
def test_lambda_is_the_smith_projected_area(dist):
    """Independent check of Λ: cosθi (1 + Λ(wi)) = ∫ max(0, wi·m) D(m) dm (Heitz 2014 eq. 17),
    by quadrature over m (no G1 involved)."""
    mf = Microfacet(dist, 0.4, 0.15)
    grid = Grid(16, 32, 0.0, 1.0)
    for theta, phi in ((20.0, 0.2), (70.0, 1.3), (86.0, 2.5)):
        wi = direction(theta, phi)
        proj = grid.integrate(lambda m: np.maximum(m @ wi, 0.0) * mf.D(m), tol=1e-9).sum()
        lam = mf.smith_lambda(wi[None, :])[0]
        assert proj == pytest.approx(wi[2] * (1.0 + lam), rel=2e-4)


def test_beckmann_rational_g1_close_to_exact():
    # Walter et al. 2007 report the rational fit as accurate to well under 1 %.
    sep = Microfacet("beckmann", 0.5, masking="separable")
    exact = Microfacet("beckmann", 0.5)
    ct = np.linspace(0.02, 1.0, 200)
    w = spherical_directions(ct, np.zeros_like(ct))
    m = np.tile([0.0, 0.0, 1.0], (ct.size, 1))
    a = sep._G1_separable(w, m)
    b = exact.G1(w, m)
    assert np.max(np.abs(a - b)) < 4e-3


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
@pytest.mark.parametrize("masking", ["height-correlated", "separable"])
def test_extreme_alpha_and_cosines_are_finite(dist, masking):
    rng = np.random.default_rng(3)
    for alpha in (0.0, 1e-6, 1e-4, 1e-2, 1.0):
        mf = Microfacet(dist, alpha, alpha * 0.5, masking)
        for cz in (0.0, 1e-12, 1e-6, 1e-3, 1.0):
            wi = np.tile([math.sqrt(1 - cz * cz), 0.0, cz], (64, 1))
            m = mf.sample_visible(wi, rng.random((64, 2)))
            wo = 2 * (wi * m).sum(1)[:, None] * m - wi
            vals = [m, mf.D(m), mf.smith_lambda(wi), mf.G1(wi, m), mf.G(wi, wo, m),
                    mf.pdf_visible(wi, m), mf.pdf_ndf(m), mf.sample_ndf(rng.random((64, 2)))]
            for v in vals:
                assert np.all(np.isfinite(v)), (alpha, cz)
            assert np.all(m[:, 2] > 0) and np.allclose(np.linalg.norm(m, axis=1), 1.0)


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
def test_anisotropic_ndf_matches_textbook_form(dist):
    """D in spherical form (Walter et al. 2007 / Heitz 2014, anisotropic), written out here."""
    au, av = 0.35, 0.08
    mf = Microfacet(dist, au, av)
    rng = np.random.default_rng(2)
    th = rng.uniform(0, 0.49 * np.pi, 500)
    ph = rng.uniform(0, 2 * np.pi, 500)
    m = spherical_directions(np.cos(th), ph)
    t2 = np.tan(th) ** 2 * (np.cos(ph) ** 2 / au ** 2 + np.sin(ph) ** 2 / av ** 2)
    c4 = np.cos(th) ** 4
    if dist == "ggx":
        ref = 1.0 / (np.pi * au * av * c4 * (1.0 + t2) ** 2)
    else:
        ref = np.exp(-t2) / (np.pi * au * av * c4)
    np.testing.assert_allclose(mf.D(m), ref, rtol=1e-10, atol=1e-300)
    assert np.all(mf.D(-m) == 0)
