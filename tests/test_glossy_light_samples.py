"""Several next-event samples at glossy vertices (``render.glossy_light_samples``): at a rough
conductor each light is sampled K times, each sample weighted 1/K, and emission found by BSDF
sampling from there is weighted by the power heuristic with K light samples against one BSDF
sample. The image must not change beyond noise (both next-event paths: every light sampled, and
one light picked per sample), only its noise on the metal."""
import numpy as np
import pytest

from render_util import region_z, render
from test_nee_all_lights import _nee_all, strips_under_lights

from backend.errors import SceneError


def _strips(mode, spp, k):
    data = strips_under_lights(mode, spp)
    data["render"]["glossy_light_samples"] = k
    data["render"]["seed"] = 11 + int(k)      # independent renders: the z-scores are honest
    return data


@pytest.mark.parametrize("mode", ["local", "power"])
def test_more_light_samples_at_glossy_vertices_leave_the_image_unchanged(mode):
    one = render(_strips(mode, 1024, 1))
    four = render(_strips(mode, 1024, 4))
    assert _nee_all(_strips(mode, 1, 4)) == (3 if mode == "local" else 0)   # both paths covered
    z = region_z(one, four, 3)                # columns: grey, gold, coat strips
    print(f"\n{mode}: largest |z| over 9 regions × 3 channels: {z.max():.2f}")
    assert z.max() <= 4.0, z
    # The point of it: less noise on the gold strip (the middle column), the same elsewhere.
    v1, v4 = one.film.variance_of_mean(), four.film.variance_of_mean()
    gold = (slice(None), slice(9, 15))
    print(f"gold strip variance, 4 samples / 1: {v4[gold].mean() / v1[gold].mean():.3f}")
    assert v4[gold].mean() < 0.8 * v1[gold].mean()


def test_bad_glossy_light_samples_are_refused():
    for k in (0, 9, 2.5):
        with pytest.raises(SceneError) as err:
            render(_strips("local", 1, k))
        assert "glossy_light_samples" in str(err.value), str(err.value)
