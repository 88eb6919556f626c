"""Mix and Add Shader materials (backend/materials/mix.py): the per-hit choice of one component
renders the mixture (mix: (1 − f)·A + f·B; add: A + B) — checked against the single material
whose BSDF is that mixture in closed form (Lambertian albedos add linearly), region by region
within 4σ (σ from both renders' own per-pixel variance; independent seeds)."""
from __future__ import annotations

import numpy as np
import pytest

from backend.errors import SceneError
from render_util import look_down_ortho, region_z, render, scene


def _plane(material: dict, seed: int, spp: int = 32) -> dict:
    mesh = {"positions": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]],
            "indices": [[0, 1, 2], [0, 2, 3]], "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]]}
    sun = {"type": "sun", "strength": 2.0, "angle": 10.0,
           "to_world": [[0.8, 0, 0.6, 0], [0, 1, 0, 0], [-0.6, 0, 0.8, 0], [0, 0, 0, 1]]}
    return scene(24, 24, look_down_ortho(1.0), {"m": material}, {"plane": mesh},
                 [{"mesh": "plane", "materials": ["m"]}], [sun],
                 world={"type": "constant", "color": [0.3, 0.35, 0.4]},
                 render={"spp": spp, "max_bounces": 2, "seed": seed})


def _diffuse(c):
    return {"type": "diffuse", "color": c}


def _agree(a: dict, b: dict) -> None:
    z = region_z(render(_plane(a, 1)), render(_plane(b, 2)), 3)
    assert np.all(z < 4.0), z.max()


def test_mix_of_two_lamberts_is_the_lambert_of_the_mixed_albedo():
    a, b, f = [0.8, 0.2, 0.1], [0.1, 0.3, 0.9], 0.3
    mixed = [(1 - f) * x + f * y for x, y in zip(a, b)]
    _agree({"type": "mix", "factor": f, "materials": [_diffuse(a), _diffuse(b)]}, _diffuse(mixed))


def test_add_of_lamberts_is_the_lambert_of_the_summed_albedo():
    parts = [[0.2, 0.1, 0.05], [0.3, 0.2, 0.1], [0.1, 0.4, 0.3]]
    total = [sum(c) for c in zip(*parts)]
    _agree({"type": "add", "materials": [_diffuse(c) for c in parts]}, _diffuse(total))


def test_nested_mix_and_factors_zero_and_one():
    a, b, c = [0.8, 0.8, 0.8], [0.1, 0.1, 0.1], [0.4, 0.6, 0.2]
    inner = {"type": "mix", "factor": 0.5, "materials": [_diffuse(a), _diffuse(b)]}
    outer = {"type": "mix", "factor": 0.25, "materials": [inner, _diffuse(c)]}
    expect = [0.75 * (0.5 * x + 0.5 * y) + 0.25 * z for x, y, z in zip(a, b, c)]
    _agree(outer, _diffuse(expect))
    # factor 0 and 1 are the components themselves, bit for bit (the choice is certain)
    only_b = render(_plane({"type": "mix", "factor": 1.0, "materials": [_diffuse(a), _diffuse(b)]}, 1))
    plain_b = render(_plane(_diffuse(b), 1))
    np.testing.assert_array_equal(only_b.film.combined(), plain_b.film.combined())


def test_mix_of_a_metal_and_a_lambert_matches_the_weighted_sum_of_renders():
    """A conductor and a diffuse mixed 50/50: the mean of the two pure renders (each unbiased)."""
    metal = {"type": "conductor", "metal": "Au", "roughness": 0.3}
    mix = render(_plane({"type": "mix", "factor": 0.5, "materials": [metal, _diffuse([0.5] * 3)]}, 1, spp=64))
    ra, rb = render(_plane(metal, 2, spp=64)), render(_plane(_diffuse([0.5] * 3), 3, spp=64))
    expect = 0.5 * (ra.film.combined()[..., :3] + rb.film.combined()[..., :3])
    var = mix.film.variance_of_mean() + 0.25 * (ra.film.variance_of_mean() + rb.film.variance_of_mean())
    got = mix.film.combined()[..., :3]
    for ys in (slice(0, 8), slice(8, 16), slice(16, 24)):
        for xs in (slice(0, 8), slice(8, 16), slice(16, 24)):
            d = got[ys, xs].mean(axis=(0, 1)) - expect[ys, xs].mean(axis=(0, 1))
            se = np.sqrt(var[ys, xs].sum(axis=(0, 1))) / 64
            assert np.all(np.abs(d) < 4 * se), (d, se)


@pytest.mark.parametrize("material, message", [
    ({"type": "mix", "materials": [_diffuse([1, 1, 1])]}, "expected 2 materials"),
    ({"type": "mix", "factor": 1.5, "materials": [_diffuse([1, 1, 1])] * 2}, "factor"),
    ({"type": "add", "materials": [_diffuse([1, 1, 1])] * 9}, "expected 2 to 8 materials"),
    ({"type": "mix", "materials": [{"type": "diffuse", "emission": [1, 1, 1]}, _diffuse([1, 1, 1])]},
     "cannot emit"),
])
def test_bad_mixes_are_refused_with_a_message(material, message):
    with pytest.raises(SceneError, match=message):
        render(_plane(material, 1, spp=1))
