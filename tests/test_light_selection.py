"""Light selection: per-point probabilities match their sampling, and both modes render the same
image (unbiased), the local one with less noise when lights are at different distances."""
import numpy as np
from scipy import stats as sst

from backend.lights.area import AreaLight
from backend.lights.point import PointLight
from backend.lights.selection import LightSelector, build_selector
from backend.lights.sun import SunLight
from render_util import look_down_ortho, region_z, render, scene


def translate(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def test_local_selection_samples_with_the_reported_probability():
    lights = [PointLight(translate(0, 0, 1), 100.0, [1, 1, 1]),
              PointLight(translate(5, 0, 1), 400.0, [1, 1, 1]),
              AreaLight(translate(0, 3, 2), "square", 1.0, 1.0, 50.0, [1, 1, 1])]
    sel = build_selector(lights, "local", radius=10.0)
    rng = np.random.default_rng(0)
    n = 60_000
    for point in ([0.2, 0.1, 0.0], [4.0, 0.0, 0.5], [0.0, 3.0, 3.0]):   # the last is behind the area light
        p = np.tile(point, (n, 1))
        idx, prob = sel.sample_at(p, rng.random(n))
        expected = np.array([sel.prob_at(p[:1], i)[0] for i in range(3)])
        assert abs(expected.sum() - 1) < 1e-12
        assert np.allclose(prob, expected[idx])
        counts = np.bincount(idx, minlength=3)
        pos = expected > 0
        assert np.all(counts[~pos] == 0)
        if pos.sum() > 1:
            assert sst.chisquare(counts[pos], n * expected[pos]).pvalue > 1e-3


def test_power_mode_is_the_global_table():
    lights = [PointLight(translate(0, 0, 1), 100.0, [1, 1, 1]), SunLight(np.eye(4), 3.0, [1, 1, 1], 0.0)]
    for light in lights:
        light.prepare(np.zeros(3), 10.0)
    sel = build_selector(lights, "power", radius=10.0)
    p = np.random.default_rng(1).normal(size=(5, 3))
    assert np.allclose(sel.prob_at(p, 0), sel.pmf[0])
    assert isinstance(sel, LightSelector) and not sel.local


def two_light_floor(mode, spp):
    # A large sunlit floor with a small area light near one corner: lights at very different
    # "distances", the case where a global power table starves the area light.
    sun = {"type": "sun", "to_world": [[1, 0, 0, 0], [0, 0.8, -0.6, 0], [0, 0.6, 0.8, 10], [0, 0, 0, 1]],
           "strength": 1.5, "color": [1, 1, 1], "angle": 2.0}
    area = {"type": "area", "to_world": [[1, 0, 0, -0.5], [0, 1, 0, 0.5], [0, 0, 1, 1.0], [0, 0, 0, 1]],
            "shape": "square", "size": 0.5, "power": 40.0, "color": [1, 1, 1]}
    return scene(32, 32, look_down_ortho(1.5, height=5.0), {"grey": {"type": "diffuse", "color": 0.5}},
                 {"floor": {"shape": "rectangle", "size": [60, 60]}}, [{"mesh": "floor", "materials": ["grey"]}],
                 lights=[sun, area], render={"spp": spp, "max_bounces": 0, "seed": 5, "light_selection": mode})


def test_local_and_power_selection_agree_and_local_is_less_noisy(monkeypatch):
    # One picked light per vertex in both (two lights would otherwise both be sampled:
    # backend/integrator.ALL_LIGHTS_MAX, tested in test_nee_all_lights.py).
    monkeypatch.setattr("backend.integrator.ALL_LIGHTS_MAX", 0)
    a = render(two_light_floor("local", 64))
    b = render(two_light_floor("power", 64))
    va, vb = a.film.variance_of_mean(), b.film.variance_of_mean()
    z = region_z(a, b, 2)
    assert z.max() <= 4, z
    noise_local = np.sqrt(va.mean())
    noise_power = np.sqrt(vb.mean())
    print(f"\nmean standard error per pixel: local {noise_local:.5f}, power {noise_power:.5f}")
    assert noise_local < 0.7 * noise_power
