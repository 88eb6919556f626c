"""Area lights: closed-form irradiance, power normalisation (Cycles ≥ 4.0: L = P/(π A_world)),
Blender's spread, and the sampling density that MIS relies on."""
import numpy as np
import pytest

from backend.lights.area import AreaLight, CollimatedAreaLight
from backend.lights.profiles import CyclesSpread, Lambertian

from lights_util import (K_SIGMA, bsdf_irradiance, check_mis_consistency, chi2_on_plane,
                         nee_irradiance, rect_irradiance_parallel, rot_x, rot_z, translate)

P = 50.0
COLOR = np.array([1.0, 0.7, 0.4])


def light_down(shape, su, sv, height=1.0, linear=None, profile=None, power=P, normalize=True):
    """An area light at (0, 0, height) shining down −Z (its local −Z)."""
    return AreaLight(translate(0, 0, height, linear), shape, su, sv, power, COLOR, normalize, profile)


# The last two points see the light nearly uniformly and are area-sampled (AREA_SAMPLING_R2_RATIO).
@pytest.mark.parametrize("p", [[0.0, 0.0, 0.0], [0.3, -0.2, 0.4], [1.5, 0.9, 0.0], [0.2, 0.1, -5.0], [3.0, -2.0, -9.0]])
def test_rectangle_irradiance_closed_form(p):
    """Receiver parallel to a 1 × 2 rectangle; scale (1.5, 0.5) on the object is part of the size."""
    light = light_down("rectangle", 1.0, 4.0, 1.0, linear=np.diag([1.5, 0.5, 1.0]))
    lx, ly = 1.5, 2.0                                   # world size
    L = COLOR * P / (np.pi * lx * ly)
    h = 1.0 - p[2]
    expected = rect_irradiance_parallel(-lx / 2 - p[0], lx / 2 - p[0], -ly / 2 - p[1], ly / 2 - p[1], h, L)
    rng = np.random.default_rng(10)
    mean, se, _ = nee_irradiance(light, p, [0, 0, 1], 20000, rng)
    assert np.all(np.abs(mean - expected) <= K_SIGMA * se + 1e-12), (mean, expected, se)
    mean_b, se_b = bsdf_irradiance(light, p, [0, 0, 1], 100000, rng)
    assert np.all(np.abs(mean_b - expected) <= K_SIGMA * se_b), (mean_b, expected, se_b)


@pytest.mark.parametrize("h", [0.2, 1.0, 5.0])
def test_disk_on_axis_irradiance(h):
    r = 0.75
    light = light_down("disk", 2 * r, 2 * r, h)
    L = COLOR * P / (np.pi * np.pi * r * r)
    expected = np.pi * L * r * r / (r * r + h * h)
    rng = np.random.default_rng(11)
    mean, se, _ = nee_irradiance(light, [0, 0, 0], [0, 0, 1], 40000, rng)
    assert np.all(np.abs(mean - expected) <= K_SIGMA * se), (mean, expected, se)


def test_light_behind_or_backside_gives_nothing():
    light = light_down("square", 1.0, 1.0, 1.0)
    rng = np.random.default_rng(12)
    s = light.sample(np.array([[0.0, 0.0, 2.0], [3.0, 0.0, 1.0]]), rng.random((2, 2)))
    assert np.all(s.value == 0) and np.all(s.pdf == 0)
    # a ray from above going down passes through the back of the emitter: no hit
    t = light.intersect(np.array([[0.0, 0.0, 2.0]]), np.array([[0.0, 0.0, -1.0]]), np.array([np.inf]))
    assert np.isinf(t).all()


@pytest.mark.parametrize("shape, profile", [("rectangle", Lambertian()), ("ellipse", Lambertian()),
                                            ("rectangle", CyclesSpread(np.radians(60))),
                                            ("disk", CyclesSpread(np.radians(20)))])
def test_flux_leaving_a_normalized_area_light_equals_power(shape, profile):
    """Irradiance integrated over a sphere of radius R around the light equals P — Cycles'
    spread keeps the power too. Monte Carlo over uniform points of the sphere."""
    light = AreaLight(translate(0.1, 0.2, 0.3, rot_x(30) @ np.diag([1.0, 2.0, 1.0])), shape, 0.8, 0.5,
                      P, [1, 1, 1], True, profile)
    R = 1.5
    rng = np.random.default_rng(13)
    n = 200000
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    pts = np.array([0.1, 0.2, 0.3]) + R * dirs
    s = light.sample(pts, rng.random((n, 2)))
    flux = s.value[:, 0] * np.maximum(np.einsum("ij,ij->i", s.wi, -dirs), 0) * 4 * np.pi * R * R
    assert abs(flux.mean() - P) <= K_SIGMA * flux.std() / np.sqrt(n), (flux.mean(), flux.std() / np.sqrt(n))


def test_unnormalized_area_light_radiance():
    """normalize = false: radiance P/π whatever the size (Cycles' invarea = 1)."""
    light = light_down("square", 3.0, 3.0, 1.0, normalize=False, power=2.0)
    le = light.eval_hit(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), np.ones(1))
    assert np.allclose(le, COLOR * 2.0 / np.pi)
    assert light.power() == pytest.approx(2.0 * 9.0 * float(COLOR @ [0.2126, 0.7152, 0.0722]))


def cycles_spread_radiance(spread, cos_out, L0):
    """Cycles area.h: eval = L0 · (tan(s/2) − tan θ) / (tan(s/2) − s/2), clamped at 0."""
    a = spread / 2
    tan_t = np.sqrt(1 - cos_out ** 2) / cos_out
    return L0 * np.maximum(np.tan(a) - tan_t, 0) / (np.tan(a) - a)


@pytest.mark.parametrize("p", [[0.0, 0.0, 0.0], [0.5, 0.1, 0.3], [1.2, 0.0, 0.0]])
def test_spread_irradiance_matches_quadrature(p):
    spread = np.radians(50.0)
    light = light_down("rectangle", 1.0, 0.6, 1.0, profile=CyclesSpread(spread))
    L0 = P / (np.pi * 0.6)
    p = np.array(p)
    # quadrature over the emitter: E = ∫ L(θ) cos θ_l cos θ_r / t² dA
    k = 800
    xs = (np.arange(k) + 0.5) / k - 0.5
    ys = ((np.arange(k) + 0.5) / k - 0.5) * 0.6
    X, Y = np.meshgrid(xs, ys)
    v = np.stack([X - p[0], Y - p[1], np.full_like(X, 1.0 - p[2])], axis=-1)
    t2 = (v ** 2).sum(-1)
    cos = v[..., 2] / np.sqrt(t2)
    e_ref = np.sum(cycles_spread_radiance(spread, cos, L0) * cos * cos / t2) / (k * k) * 0.6
    rng = np.random.default_rng(14)
    mean, se, s = nee_irradiance(light, p, [0, 0, 1], 40000, rng)
    assert abs(mean[0] / COLOR[0] - e_ref) <= K_SIGMA * se[0] / COLOR[0] + 2e-4 * e_ref, (mean, e_ref, se)
    if e_ref == 0:
        assert np.all(s.value == 0) and np.all(s.pdf == 0)


def test_collimated_spread_zero():
    """spread = 0 (Cycles' limit): irradiance P/A along the normal under the emitter, 0 elsewhere."""
    light = CollimatedAreaLight(translate(0, 0, 2, np.diag([2.0, 1.0, 1.0])), "square", 1.0, 1.0, P, COLOR)
    pts = np.array([[0.9, 0.4, 0.0], [1.1, 0.0, 0.0], [0.0, 0.0, 3.0]])
    s = light.sample(pts, np.zeros((3, 2)))
    assert np.allclose(s.value[0], COLOR * P / 2.0) and np.allclose(s.wi[0], [0, 0, 1])
    assert np.all(s.value[1:] == 0) and light.is_delta


def sampled_region(o, half_u, half_v, tan_cutoff):
    """Where a point at height h can receive light from: the emitter clipped to the square box
    around its projection of half-width h · tan(cutoff) (emitter frame, emitter at the origin)."""
    pu, pv, h = o
    r = h * tan_cutoff
    return ((max(-half_u, pu - r), min(half_u, pu + r)), (max(-half_v, pv - r), min(half_v, pv + r)))


@pytest.mark.parametrize("shape, where, profile", [
    ("rectangle", [0.2, 0.1, 0.0], Lambertian()),
    ("rectangle", [2.5, 0.3, 0.7], Lambertian()),            # grazing, off to the side
    ("rectangle", [0.4, -0.3, -4.0], Lambertian()),          # far: area-sampled, nearly uniform
    ("ellipse", [0.3, -0.2, 0.2], Lambertian()),
    ("rectangle", [0.6, 0.0, 0.2], CyclesSpread(np.radians(40))),   # clipped region
    ("disk", [0.3, 0.2, 0.5], CyclesSpread(np.radians(30))),        # clipped box of a disk
    ("ellipse", [0.7, 0.2, 0.8], CyclesSpread(np.radians(100))),    # box larger than the ellipse
])
def test_area_sampling_matches_pdf_hit(shape, where, profile):
    rot = rot_z(20)
    light = AreaLight(translate(0, 0, 1, rot), shape, 1.6, 1.0, P, COLOR, True, profile)
    o = np.array(where, float)
    rng = np.random.default_rng(15)
    check_mis_consistency(light, o, 4000, rng)
    local = np.array([(o - [0, 0, 1]) @ rot[:, 0], (o - [0, 0, 1]) @ rot[:, 1], 1.0 - o[2]])
    half_v = 0.8 if shape == "disk" else 0.5
    ur, vr = sampled_region(local, 0.8, half_v, profile.tan_max)
    p_value, outside, mass = chi2_on_plane(light, o, [0, 0, 1], rot[:, 0], rot[:, 1], ur, vr, 150000, rng)
    assert outside == 0 and p_value > 0.01, (p_value, outside, mass)


def test_solid_angle_sampling_of_a_tiny_far_light_stays_consistent():
    """A 1 cm light 100 m away (solid angle 1e-8 sr): area-sampling fallback, same estimate."""
    light = light_down("square", 0.01, 0.01, 100.0)
    rng = np.random.default_rng(16)
    mean, se, s = nee_irradiance(light, [0.0, 0.0, 0.0], [0, 0, 1], 1000, rng)
    L = COLOR * P / (np.pi * 1e-4)
    expected = rect_irradiance_parallel(-0.005, 0.005, -0.005, 0.005, 100.0, L)
    assert np.allclose(mean, expected, rtol=1e-6)
    check_mis_consistency(light, [0.0, 0.0, 0.0], 200, rng)


def test_area_sampling_switch_is_where_the_density_is_nearly_uniform():
    """The whole-rectangle sampler switches from the spherical rectangle to area sampling where
    (r_max / r_min)³ ≤ 2. Checked against brute force over the rectangle: the ratio of the
    area density in solid angle (r³/(A h)) between its largest and smallest value on a fine grid."""
    from backend.kernels.lights.area import AREA_SAMPLING_R2_RATIO, _nearly_uniform
    rng = np.random.default_rng(21)
    g = np.linspace(0.0, 1.0, 201)
    agree = 0
    for _ in range(300):
        x0, y0 = rng.uniform(-3, 1, 2)
        lx, ly = rng.uniform(0.05, 2, 2)
        z0 = -rng.uniform(0.1, 8)
        X, Y = np.meshgrid(x0 + g * lx, y0 + g * ly)
        r2 = X * X + Y * Y + z0 * z0
        # the nearest point of the rectangle (it may be inside: the foot of the perpendicular)
        r2_min = min(r2.min(), np.clip(0.0, x0, x0 + lx) ** 2 + np.clip(0.0, y0, y0 + ly) ** 2 + z0 * z0)
        ratio = r2.max() / r2_min
        if abs(ratio - AREA_SAMPLING_R2_RATIO) < 1e-3:
            continue                                            # grid resolution
        assert _nearly_uniform(x0, y0, z0, lx, ly) == (ratio <= AREA_SAMPLING_R2_RATIO)
        agree += 1
    assert agree > 250
