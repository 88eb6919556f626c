"""Local light selection weighs an area light with an angular profile (``spread``) by that profile
towards the shading point (kernels/lights/selection.py, SEL_ONE_SIDED_PROFILE): the probabilities
are what sampling does, the image does not change (local vs power selection within K_SIGMA
standard errors, σ from the renders' own per-pixel variance, fixed seeds), and the noise where the
beam points falls."""
import numpy as np
from scipy import stats as sst

from backend.lights.area import AreaLight
from backend.lights.point import PointLight
from backend.lights.profiles import CyclesSpread
from backend.lights.selection import build_selector
from render_util import look_down_ortho, region_z, render, scene

K_SIGMA = 4.0


def translate(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def _lights(spread_deg):
    # An area light 1 m above the origin facing down (emits along local −Z), and a point light.
    profile = CyclesSpread(np.radians(spread_deg)) if spread_deg is not None else None
    return [AreaLight(translate(0, 0, 1), "square", 0.5, 0.5, 50.0, [1, 1, 1], profile=profile),
            PointLight(translate(2, 0, 1), 30.0, [1, 1, 1])]


def test_profile_weighs_the_selection_and_sampling_matches_it():
    spread, lamb = build_selector(_lights(40.0), "local", 10.0), build_selector(_lights(None), "local", 10.0)
    on_axis, off_axis = np.array([[0.0, 0.0, 0.0]]), np.array([[1.6, 0.0, 0.0]])
    # On the beam's axis the 40° spread light receives 1/K ≈ 15× a Lambertian one of the same power.
    k = CyclesSpread(np.radians(40.0)).normalization
    ratio = spread.weights_at(on_axis)[0, 0] / lamb.weights_at(on_axis)[0, 0]
    assert abs(ratio - 1.0 / k) < 1e-9 * ratio
    # Outside the beam: a small share, never none (an edge of the emitter may still reach it).
    p_off = spread.prob_at(off_axis, 0)[0]
    assert 0.0 < p_off < lamb.prob_at(off_axis, 0)[0]
    rng = np.random.default_rng(3)
    n = 60_000
    for point in (on_axis[0], off_axis[0], [0.7, 0.3, 0.2]):
        p = np.tile(point, (n, 1))
        idx, prob = spread.sample_at(p, rng.random(n))
        expected = np.array([spread.prob_at(p[:1], i)[0] for i in range(2)])
        assert abs(expected.sum() - 1) < 1e-12 and np.allclose(prob, expected[idx])
        counts = np.bincount(idx, minlength=2)
        assert sst.chisquare(counts, n * expected).pvalue > 1e-3


def _floor(mode, spp):
    area = {"type": "area", "to_world": [[1, 0, 0, -0.6], [0, 1, 0, 0], [0, 0, 1, 1.0], [0, 0, 0, 1]],
            "shape": "square", "size": 0.5, "power": 20.0, "color": [1, 1, 1], "spread": 40.0}
    point = {"type": "point", "to_world": [[1, 0, 0, 0.8], [0, 1, 0, 0], [0, 0, 1, 0.6], [0, 0, 0, 1]],
             "power": 40.0, "color": [1, 1, 1]}
    return scene(32, 32, look_down_ortho(1.5, height=5.0), {"grey": {"type": "diffuse", "color": 0.5}},
                 {"floor": {"shape": "rectangle", "size": [3, 3]}}, [{"mesh": "floor", "materials": ["grey"]}],
                 lights=[area, point], render={"spp": spp, "max_bounces": 0, "seed": 9, "light_selection": mode})


def test_local_selection_with_a_spread_light_is_unbiased_and_less_noisy_under_the_beam(monkeypatch):
    # The one-light pick in both modes (with two lights the renderer would otherwise sample both:
    # backend/integrator.ALL_LIGHTS_MAX).
    monkeypatch.setattr("backend.integrator.ALL_LIGHTS_MAX", 0)
    a, b = render(_floor("local", 64)), render(_floor("power", 64))
    va, vb = a.film.variance_of_mean(), b.film.variance_of_mean()
    z = region_z(a, b, 2)
    assert z.max() <= K_SIGMA, z
    # Under the beam (the area light is over the left half, x = −0.6 m): less noise than power
    # selection, which gives the brighter point light most samples everywhere.
    beam = (slice(10, 22), slice(6, 14))
    assert va[beam].mean() < 0.5 * vb[beam].mean(), (va[beam].mean(), vb[beam].mean())
