"""Directional area light (cutoff_angle / beam_width, smoothstep in angle): equals the Lambertian
light at 90°, matches quadrature over the emitter, never samples towards points outside its cone,
and its NEE and BSDF-hit estimates agree (the MIS pair)."""
import numpy as np
import pytest
from scipy import integrate

from backend.lights.area import AreaLight
from backend.lights.profiles import Lambertian, SmoothCone

from lights_util import K_SIGMA, bsdf_irradiance, check_mis_consistency, cosine_directions, nee_irradiance, rot_x, translate

P = 30.0
SIZE_U, SIZE_V = 1.2, 0.8


def dv_light(cutoff_deg, beam_deg, shape="rectangle", linear=None):
    return AreaLight(translate(0, 0, 1.0, linear), shape, SIZE_U, SIZE_V, P, [1, 1, 1], True,
                     SmoothCone(np.radians(cutoff_deg), np.radians(beam_deg)))


def reference_profile(cutoff, beam):
    """f(θ) and its normalisation K = 2∫ f cos sin dθ, written independently (scipy quad)."""
    def f(theta):
        theta = np.asarray(theta, float)
        s = np.clip((cutoff - theta) / (cutoff - beam), 0, 1) if cutoff > beam else (theta <= cutoff) * 1.0
        ramp = s * s * (3 - 2 * s)
        return np.where(theta <= beam, 1.0, np.where(theta >= cutoff, 0.0, ramp))
    k = integrate.quad(lambda t: 2 * f(t) * np.cos(t) * np.sin(t), 0, np.pi / 2, points=[beam, cutoff],
                       epsabs=1e-13, epsrel=1e-12)[0]
    return f, k


def quadrature_irradiance(p, normal, cutoff, beam, k=900):
    """E = ∫_A L(θ) cos θ_l cos θ_r / t² dA over the emitter at z = 1 (shining down), midpoint."""
    f, K = reference_profile(cutoff, beam)
    L0 = P / (np.pi * SIZE_U * SIZE_V * K)
    xs = ((np.arange(k) + 0.5) / k - 0.5) * SIZE_U
    ys = ((np.arange(k) + 0.5) / k - 0.5) * SIZE_V
    X, Y = np.meshgrid(xs, ys)
    v = np.stack([X - p[0], Y - p[1], np.full_like(X, 1.0 - p[2])], axis=-1)
    t = np.linalg.norm(v, axis=-1)
    w = v / t[..., None]
    cos_l = w[..., 2]
    cos_r = np.maximum(w @ normal, 0)
    theta = np.arccos(np.clip(cos_l, -1, 1))
    return np.sum(L0 * f(theta) * cos_l * cos_r / (t * t)) * (SIZE_U * SIZE_V) / (k * k)


def test_cutoff_90_without_smoothing_equals_lambertian_exactly():
    a = dv_light(90.0, 90.0)
    b = AreaLight(translate(0, 0, 1.0), "rectangle", SIZE_U, SIZE_V, P, [1, 1, 1], True, Lambertian())
    rng = np.random.default_rng(20)
    pts = np.column_stack([rng.uniform(-2, 2, 5000), rng.uniform(-2, 2, 5000), rng.uniform(-1, 0.9, 5000)])
    u = rng.random((5000, 2))
    sa, sb = a.sample(pts, u), b.sample(pts, u)
    assert np.array_equal(sa.value, sb.value) and np.array_equal(sa.pdf, sb.pdf)
    assert np.array_equal(sa.wi, sb.wi)
    assert a.power() == b.power()


@pytest.mark.parametrize("cutoff, beam", [(20.0, 5.0), (12.0, 12.0), (35.0, 0.0)])
def test_narrow_cone_irradiance_matches_quadrature(cutoff, beam):
    rng = np.random.default_rng(21)
    light = dv_light(cutoff, beam)
    c, b = np.radians(cutoff), np.radians(beam)
    points = [([0.0, 0.0, 0.0], [0, 0, 1]),               # under the centre
              ([0.5, 0.3, 0.2], [0, 0, 1]),               # partly lit (cone clips the emitter)
              ([0.2, -0.1, -0.5], [0.3, 0.2, 0.93])]      # tilted receiver
    for p, n in points:
        p, n = np.array(p), np.array(n) / np.linalg.norm(n)
        ref = quadrature_irradiance(p, n, c, b)
        assert ref > 0
        mean, se, s = nee_irradiance(light, p, n, 40000, rng)
        # the quadrature error is below 1e-3 relative (halving k changes it by less)
        assert abs(mean[0] - ref) <= K_SIGMA * se[0] + 1e-3 * ref, (p, mean, ref, se)
        lit = np.any(s.value > 0, axis=1)
        theta = np.degrees(np.arccos(np.clip(s.wi[lit, 2], -1, 1)))   # emission angle to the normal −Z
        assert np.all(theta <= cutoff + 1e-9)


def test_points_outside_the_cone_get_no_samples():
    light = dv_light(15.0, 5.0)
    # The emitter spans |x| ≤ 0.6, |y| ≤ 0.4 at z = 1; at height h below it the lit footprint
    # reaches h·tan 15° beyond the edges. These points are beyond that:
    pts = np.array([[0.6 + 1.0 * np.tan(np.radians(15)) + 0.01, 0.0, 0.0],
                    [0.0, 0.4 + 2.0 * np.tan(np.radians(15)) + 0.01, -1.0],
                    [5.0, 5.0, -3.0]])
    s = light.sample(pts, np.random.default_rng(22).random((3, 2)))
    assert np.all(s.value == 0) and np.all(s.pdf == 0)
    # ... and a point just inside the footprint does receive light
    inside = np.array([[0.6 + 1.0 * np.tan(np.radians(15)) - 0.05, 0.0, 0.0]])
    n = 20000
    s = light.sample(np.repeat(inside, n, axis=0), np.random.default_rng(23).random((n, 2)))
    assert np.any(s.value > 0)


def test_no_shadow_rays_wasted_for_partly_lit_points():
    """A shadow ray is needed only for samples that carry light (value > 0): all of those leave
    the emitter inside the cone, and restricting sampling to the cone's footprint makes far more
    samples useful than sampling the whole emitter would."""
    cutoff = np.radians(20.0)
    light = dv_light(20.0, 5.0)
    whole = AreaLight(translate(0, 0, 1.0), "rectangle", SIZE_U, SIZE_V, P, [1, 1, 1], True, Lambertian())
    rng = np.random.default_rng(24)
    n = 20000
    pts = np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-1.5, 1.5, n), rng.uniform(-2, 0.5, n)])
    u = rng.random((n, 2))
    s = light.sample(pts, u)
    carrying = np.any(s.value > 0, axis=1)
    assert np.all(np.arccos(np.clip(s.wi[carrying, 2], -1, 1)) < cutoff)
    t = light.intersect(pts[carrying], s.wi[carrying], np.full(int(carrying.sum()), np.inf))
    assert np.all(np.isfinite(t))
    # points that receive some light: compare the useful fraction with whole-emitter sampling
    lit = np.array([quadrature_irradiance(p, np.array([0, 0, 1.0]), cutoff, np.radians(5), k=60) > 0
                    for p in pts[:2000]])
    sw = whole.sample(pts[:2000][lit], u[:2000][lit])
    useful_whole = np.mean((sw.pdf > 0) & (np.arccos(np.clip(sw.wi[:, 2], -1, 1)) < cutoff))
    useful_cone = np.mean(carrying[:2000][lit])
    assert useful_cone > useful_whole, (useful_cone, useful_whole)


@pytest.mark.parametrize("shape", ["rectangle", "ellipse"])
def test_nee_and_bsdf_estimates_agree_with_each_other_and_quadrature(shape):
    """The two strategies of the MIS pair, and their power-heuristic combination."""
    cutoff, beam = 25.0, 10.0
    light = dv_light(cutoff, beam, shape)
    rng = np.random.default_rng(25)
    p, n = np.array([0.3, -0.1, 0.1]), np.array([0.0, 0.0, 1.0])
    m_nee, se_nee, _ = nee_irradiance(light, p, n, 100000, rng)
    m_bsdf, se_bsdf = bsdf_irradiance(light, p, n, 400000, rng)
    assert abs(m_nee[0] - m_bsdf[0]) <= K_SIGMA * np.hypot(se_nee[0], se_bsdf[0]), (m_nee, m_bsdf)
    if shape == "rectangle":
        ref = quadrature_irradiance(p, n, np.radians(cutoff), np.radians(beam))
        assert abs(m_nee[0] - ref) <= K_SIGMA * se_nee[0] + 1e-3 * ref
        assert abs(m_bsdf[0] - ref) <= K_SIGMA * se_bsdf[0] + 1e-3 * ref
    # MIS: one light sample + one cosine sample per estimate, power heuristic
    N = 100000
    pts = np.repeat(p[None], N, axis=0)
    s = light.sample(pts, rng.random((N, 2)))
    cos_l = np.maximum(s.wi @ n, 0)
    pb = cos_l / np.pi
    w_l = np.where(s.pdf > 0, s.pdf ** 2 / (s.pdf ** 2 + pb ** 2), 0)
    e_l = s.value[:, 0] * cos_l * w_l
    d = cosine_directions(n, N, rng)
    t = light.intersect(pts, d, np.full(N, np.inf))
    hit = np.isfinite(t)
    e_b = np.zeros(N)
    pl = light.pdf_hit(pts[hit], d[hit], t[hit])
    pbh = (d[hit] @ n) / np.pi
    e_b[hit] = light.eval_hit(pts[hit], d[hit], t[hit])[:, 0] * np.pi * pbh ** 2 / (pbh ** 2 + pl ** 2)
    e = e_l + e_b
    assert abs(e.mean() - m_nee[0]) <= K_SIGMA * np.hypot(e.std() / np.sqrt(N), se_nee[0])
    check_mis_consistency(light, p, 4000, rng)


def test_directional_light_flux_equals_power():
    light = dv_light(30.0, 10.0, linear=rot_x(40))
    R = 2.0
    rng = np.random.default_rng(26)
    n = 200000
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    s = light.sample(np.array([0, 0, 1.0]) + R * dirs, rng.random((n, 2)))
    flux = s.value[:, 0] * np.maximum(np.einsum("ij,ij->i", s.wi, -dirs), 0) * 4 * np.pi * R * R
    assert abs(flux.mean() - P) <= K_SIGMA * flux.std() / np.sqrt(n)
