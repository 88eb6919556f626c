"""Emissive triangles (Lambert's polygon formula, one-sided emission, triangle choice ∝ area ×
luminance, pdf_hit_triangle) and light selection ∝ power."""
import numpy as np
import pytest

from backend.lights.mesh import MeshLight
from backend.lights.selection import LightSelector, build_selector

from lights_util import K_SIGMA, chi2_pvalue, nee_irradiance, polygon_irradiance

LUM = np.array([0.2126, 0.7152, 0.0722])

# two triangles of a quad at z = 1, counter-clockwise seen from below (front faces −Z), plus a
# small dim triangle elsewhere
TRIS = np.array([
    [[-0.5, -0.5, 1.0], [0.5, 0.5, 1.0], [0.5, -0.5, 1.0]],
    [[-0.5, -0.5, 1.0], [-0.5, 0.5, 1.0], [0.5, 0.5, 1.0]],
    [[2.0, 0.0, 0.5], [2.0, 0.3, 0.5], [2.3, 0.0, 0.5]],
])
RAD = np.array([[4.0, 3.0, 2.0], [4.0, 3.0, 2.0], [1.0, 1.0, 1.0]])


def test_front_normal_is_counter_clockwise():
    light = MeshLight(TRIS, RAD)
    assert np.allclose(light.normal[:2], [0, 0, -1])


def test_quad_irradiance_matches_lambert_polygon_formula():
    light = MeshLight(TRIS[:2], RAD[:2])
    quad = [[-0.5, -0.5, 1.0], [0.5, -0.5, 1.0], [0.5, 0.5, 1.0], [-0.5, 0.5, 1.0]]
    rng = np.random.default_rng(40)
    for p, n in (([0.0, 0.0, 0.0], [0, 0, 1.0]), ([0.7, 0.2, 0.3], [-0.3, 0.0, 0.95])):
        p, n = np.array(p), np.array(n) / np.linalg.norm(n)
        ref = polygon_irradiance(p, n, quad, RAD[0])
        mean, se, _ = nee_irradiance(light, p, n, 100000, rng)
        assert np.all(np.abs(mean - ref) <= K_SIGMA * se), (mean, ref, se)


def test_one_sided_and_two_sided():
    above = np.array([[0.0, 0.0, 2.0]])
    s = MeshLight(TRIS[:2], RAD[:2]).sample(above, np.full((1, 2), 0.3))
    assert np.all(s.value == 0) and np.all(s.pdf == 0)
    two = MeshLight(TRIS[:2], RAD[:2], two_sided=True)
    rng = np.random.default_rng(41)
    quad = [[-0.5, -0.5, 1.0], [0.5, -0.5, 1.0], [0.5, 0.5, 1.0], [-0.5, 0.5, 1.0]]
    mean, se, _ = nee_irradiance(two, [0.0, 0.0, 2.0], [0, 0, -1.0], 50000, rng)
    ref = polygon_irradiance(np.array([0.0, 0.0, 2.0]), np.array([0, 0, -1.0]), quad, RAD[0])
    assert np.all(np.abs(mean - ref) <= K_SIGMA * se)
    assert two.power() == pytest.approx(2 * MeshLight(TRIS[:2], RAD[:2]).power())


def ray_triangle(o, d, v):
    """Möller–Trumbore for one triangle, many rays: t or inf."""
    e1, e2 = v[1] - v[0], v[2] - v[0]
    pv = np.cross(d, e2)
    det = pv @ e1
    inv = 1 / np.where(det != 0, det, 1)
    tv = o - v[0]
    u = (tv * pv).sum(1) * inv
    qv = np.cross(tv, e1)
    w = (d * qv).sum(1) * inv
    t = (qv @ e2) * inv
    ok = (det != 0) & (u >= 0) & (w >= 0) & (u + w <= 1) & (t > 0)
    return np.where(ok, t, np.inf)


def test_triangle_choice_and_pdf_hit_triangle():
    light = MeshLight(TRIS, RAD)
    area = 0.5 * np.linalg.norm(np.cross(TRIS[:, 1] - TRIS[:, 0], TRIS[:, 2] - TRIS[:, 0]), axis=1)
    expected = area * (RAD @ LUM)
    expected /= expected.sum()
    assert np.allclose(light.pmf, expected, rtol=1e-12)
    assert light.power() == pytest.approx(np.pi * float(np.sum(area * (RAD @ LUM))))
    rng = np.random.default_rng(42)
    o = np.array([0.3, 0.1, -0.5])
    n = 100000
    s = light.sample(np.repeat(o[None], n, 0), rng.random((n, 2)))
    ok = s.pdf > 0
    # which triangle each sample landed on, found by ray casting here
    t_all = np.stack([ray_triangle(np.repeat(o[None], ok.sum(), 0), s.wi[ok], v) for v in TRIS], 1)
    tri = np.argmin(t_all, 1)
    assert np.allclose(t_all[np.arange(tri.size), tri], s.dist[ok], rtol=1e-9)
    counts = np.bincount(tri, minlength=3)
    assert chi2_pvalue(counts, expected * n) > 0.01
    pdf = light.pdf_hit_triangle(np.repeat(o[None], ok.sum(), 0), s.wi[ok], s.dist[ok], tri)
    assert np.allclose(pdf, s.pdf[ok], rtol=1e-9)
    assert np.allclose(RAD[tri] / pdf[:, None], s.value[ok], rtol=1e-9)


def test_selection_probabilities_proportional_to_power():
    powers = np.array([3.0, 0.0, 1.0, 6.0, 0.0])
    sel = LightSelector(powers)
    assert np.allclose(sel.pmf, powers / powers.sum())
    rng = np.random.default_rng(43)
    idx, prob, _ = sel.sample(rng.random(200000))
    assert chi2_pvalue(np.bincount(idx, minlength=5)[[0, 2, 3]], powers[[0, 2, 3]] / 10 * 200000) > 0.01
    assert np.allclose(prob, sel.pmf[idx])
    # zero-power lights are never picked, not even exactly at the CDF's ties
    ties = np.array([0.0, 0.3, 0.4, np.nextafter(0.3, 0), np.nextafter(0.4, 0), np.nextafter(1.0, 0)])
    idx, prob, _ = sel.sample(ties)
    assert not np.isin(idx, [1, 4]).any() and np.all(prob > 0)
    assert sel.prob(1) == 0 and sel.prob(3) == pytest.approx(0.6)


class _Fake:
    def __init__(self, p):
        self.p = p

    def power(self):
        return self.p


def test_build_selector():
    assert build_selector([]) is None
    assert build_selector([_Fake(0.0), _Fake(float("nan"))]) is None
    sel = build_selector([_Fake(0.0), _Fake(2.0), _Fake(float("inf")), _Fake(2.0)])
    assert np.allclose(sel.pmf, [0, 0.5, 0, 0.5])
