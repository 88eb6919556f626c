"""Fresnel reflectance against closed forms, complex arithmetic and published metal reflectances."""
from __future__ import annotations

import math

import numpy as np
import pytest

from backend.materials.fresnel import (conductor, conductor_polarized, dielectric,
                                       dielectric_polarized)
from backend.materials.metals import METALS, metal_ior


@pytest.mark.parametrize("eta", [1.0001, 1.33, 1.5, 2.4, 0.5, 1 / 1.5])
def test_dielectric_normal_incidence(eta):
    F, cos_t, eta_ti = dielectric(1.0, eta)
    assert F == pytest.approx(((eta - 1) / (eta + 1)) ** 2, abs=1e-15)
    assert cos_t == pytest.approx(-1.0) and eta_ti == pytest.approx(eta)
    # From below the relative index is 1/eta; the normal-incidence reflectance is the same.
    F2, cos_t2, eta_ti2 = dielectric(-1.0, eta)
    assert F2 == pytest.approx(F, abs=1e-15)
    assert cos_t2 == pytest.approx(1.0) and eta_ti2 == pytest.approx(1 / eta)


@pytest.mark.parametrize("eta", [1.33, 1.5, 2.4])
def test_brewster_angle_zeroes_p_polarisation(eta):
    theta_b = math.atan(eta)   # tan θB = n2/n1
    Rs, Rp, _, _ = dielectric_polarized(math.cos(theta_b), eta)
    assert Rp == pytest.approx(0.0, abs=1e-28)
    assert Rs > 0.01
    # From the dense side the Brewster angle is atan(1/eta).
    Rs, Rp, _, _ = dielectric_polarized(-math.cos(math.atan(1 / eta)), eta)
    assert Rp == pytest.approx(0.0, abs=1e-28)


def test_total_internal_reflection():
    eta = 1.5
    crit = math.asin(1 / eta)
    cos = -np.cos(np.linspace(crit + 1e-9, math.pi / 2, 50))     # from below, beyond critical
    F, cos_t, _ = dielectric(cos, eta)
    assert np.all(F == 1.0) and np.all(cos_t == 0.0)
    cos_in = -np.cos(np.linspace(0, crit - 1e-6, 50))
    F_in, cos_t_in, _ = dielectric(cos_in, eta)
    assert np.all(F_in < 1.0) and np.all(cos_t_in > 0)


def test_dielectric_matches_closed_form_and_is_reciprocal():
    rng = np.random.default_rng(0)
    eta = rng.uniform(0.3, 3.0, 2000)
    ci = rng.uniform(-1, 1, 2000)
    F, cos_t, eta_ti = dielectric(ci, eta)
    # Textbook Fresnel with explicit n1, n2 (Hecht, Optics, §4.6).
    n1 = np.where(ci > 0, 1.0, eta)
    n2 = np.where(ci > 0, eta, 1.0)
    a = np.abs(ci)
    s_t = n1 / n2 * np.sqrt(1 - a * a)
    tir = s_t >= 1
    ct = np.sqrt(np.maximum(0, 1 - s_t ** 2))
    rs = (n1 * a - n2 * ct) / (n1 * a + n2 * ct)
    rp = (n2 * a - n1 * ct) / (n2 * a + n1 * ct)
    ref = np.where(tir, 1.0, 0.5 * (rs ** 2 + rp ** 2))
    np.testing.assert_allclose(F, ref, atol=1e-13)
    # Stokes reciprocity: the refracted ray going back sees the same reflectance.
    ok = ~tir
    F_back, cos_back, _ = dielectric(cos_t[ok], eta[ok])
    np.testing.assert_allclose(F_back, F[ok], atol=1e-12)
    np.testing.assert_allclose(np.abs(cos_back), np.abs(ci[ok]), atol=1e-9)


def test_dielectric_degenerate_inputs_are_finite():
    for ci in (0.0, -0.0, 1e-300, -1e-300, 1.0, -1.0):
        for eta in (1.0, 1e-3, 1e3):
            F, c, e = dielectric(ci, eta)
            assert np.isfinite(F) and 0 <= F <= 1 and np.isfinite(c) and np.isfinite(e)


def complex_fresnel(cos_i, n_complex):
    """Reference written directly with complex numbers (Snell with a complex index)."""
    c = np.asarray(cos_i, dtype=np.complex128)
    s2 = 1 - c * c
    ct = np.sqrt(1 - s2 / n_complex ** 2)
    rs = (c - n_complex * ct) / (c + n_complex * ct)
    rp = (n_complex * c - ct) / (n_complex * c + ct)
    return np.abs(rs) ** 2, np.abs(rp) ** 2


def test_conductor_matches_complex_arithmetic():
    rng = np.random.default_rng(1)
    cos_i = rng.uniform(0, 1, (5000, 1))
    eta = rng.uniform(0.01, 5, (5000, 3))
    k = rng.uniform(0, 10, (5000, 3))
    Rs, Rp = conductor_polarized(cos_i, eta, k)
    rs_ref, rp_ref = complex_fresnel(cos_i, eta + 1j * k)
    np.testing.assert_allclose(Rs, rs_ref, atol=1e-12)
    np.testing.assert_allclose(Rp, rp_ref, atol=1e-12)
    np.testing.assert_allclose(conductor(cos_i, eta, k), 0.5 * (rs_ref + rp_ref), atol=1e-12)


def test_conductor_limits():
    # k = 0 reduces to the dielectric Fresnel; eta = 0, k = 1 reflects everything.
    c = np.linspace(0, 1, 101)[:, None]
    np.testing.assert_allclose(conductor(c, np.array([[1.5]]), np.array([[0.0]]))[:, 0],
                               dielectric(c[:, 0], 1.5)[0], atol=1e-13)
    assert np.all(conductor(c, np.zeros((1, 3)), np.ones((1, 3))) == 1.0)
    assert np.all(conductor(c, np.zeros((1, 3)), np.zeros((1, 3))) == 1.0)
    n = np.array([[0.2, 1.0, 3.0]])
    k = np.array([[3.0, 2.0, 0.5]])
    assert np.allclose(conductor(np.ones((1, 1)), n, k), ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2))
    assert np.allclose(conductor(np.zeros((1, 1)), n, k), 1.0)


# Published normal-incidence reflectances, linear sRGB (Rec.709, D65): Hoffman, "Physics and Math
# of Shading", SIGGRAPH 2015 course notes; the same values are in Akenine-Möller et al.,
# Real-Time Rendering, 4th ed. (2018), Table 9.2. Different measurements of the same metal
# (Johnson & Christy vs. Palik, thin film vs. bulk, surface preparation) disagree by up to
# ~0.1 in reflectance, so this is a loose check (|Δ| <= 0.1 per channel) that catches wrong
# units, swapped eta/k, swapped channels or a broken Fresnel, not a precision comparison.
PUBLISHED_F0 = {
    "Ti": (0.542, 0.497, 0.449), "Cr": (0.549, 0.556, 0.554), "Fe": (0.562, 0.565, 0.578),
    "Ni": (0.660, 0.609, 0.526), "Pt": (0.673, 0.637, 0.585), "Cu": (0.955, 0.638, 0.538),
    "Pd": (0.733, 0.697, 0.652), "Hg": (0.781, 0.780, 0.778), "Zn": (0.664, 0.824, 0.850),
    "Au": (1.000, 0.782, 0.344), "Al": (0.913, 0.922, 0.924), "Ag": (0.972, 0.960, 0.915),
}


@pytest.mark.parametrize("name", sorted(PUBLISHED_F0))
def test_named_metal_normal_reflectance_matches_published(name):
    eta, k = metal_ior(name)
    f0 = conductor(np.ones((1, 1)), eta[None, :], k[None, :])[0]
    np.testing.assert_allclose(f0, PUBLISHED_F0[name], atol=0.1)


def test_required_metals_present_and_sane():
    for name in ("Ag", "Al", "Au", "Cr", "Cu", "Fe", "Ni", "Pt", "Ti", "W"):
        assert name in METALS
    for name, m in METALS.items():
        eta, k = metal_ior(name)
        assert eta.shape == (3,) and np.all(eta > 0) and np.all(k > 0), name
        f0 = conductor(np.ones((1, 1)), eta[None], k[None])[0]
        assert np.all((f0 > 0.3) & (f0 <= 1.0)), name
        assert m.source
    # Coloured metals keep their hue: gold and copper reflect red more than blue.
    for name in ("Au", "Cu"):
        eta, k = metal_ior(name)
        f0 = conductor(np.ones((1, 1)), eta[None], k[None])[0]
        assert f0[0] > f0[1] > f0[2]
