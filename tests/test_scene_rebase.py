"""Scenes far from the origin are rebased to the camera before tracing (scene/loader.py ``rebased``).

Geometry is float32 in embree: 10⁵ units out, a float32 step is 8 mm, and before rebasing the
scene below (a unit sphere on a floor, lit by a point light) rendered 0.7 % darker there than at
the origin (0.14199 vs 0.14296 ± 0.00023). Rendering does not depend on where the origin is, so the
moved scene must give the origin's image up to float rounding (which can flip a rare path's random
decision): its mean within 0.05 standard errors, its pixels within 1e-3 relative on average."""
import copy

import numpy as np
import pytest

from backend.scene.loader import REBASE_ABOVE, load_scene_data, rebased
from render_util import render, scene


def lit_sphere(spp=16):
    cam = {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0, -1, -5], [0, 1, 0, 0.5], [0, 0, 0, 1]],
           "frame": [[0.5, 0.5, -1], [0.5, -0.5, -1], [-0.5, -0.5, -1], [-0.5, 0.5, -1]]}
    coat = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.1},
                                              {"type": "diffuse", "color": 0.6}],
            "media": [{"thickness": 1, "sigma_t": 0.5, "albedo": 0.8}]}
    return scene(32, 32, cam, {"m": coat, "f": {"type": "diffuse", "color": 0.5}},
                 {"ball": {"shape": "sphere", "radius": 1.0, "segments": 48},
                  "floor": {"positions": [[-10, -10, -1], [10, -10, -1], [10, 10, -1], [-10, 10, -1]],
                            "indices": [[0, 1, 2], [0, 2, 3]]}},
                 [{"mesh": "ball", "materials": ["m"]}, {"mesh": "floor", "materials": ["f"]}],
                 lights=[{"type": "point", "to_world": [[1, 0, 0, 2], [0, 1, 0, -2], [0, 0, 1, 3], [0, 0, 0, 1]],
                          "power": 300.0, "color": [1, 1, 1]}],
                 world={"type": "constant", "color": [0.1, 0.1, 0.1], "strength": 1.0},
                 render={"spp": spp, "max_bounces": 4, "seed": 2})


def moved(data, offset):
    d = copy.deepcopy(data)
    d["camera"]["to_world"][0][3] += offset
    d["lights"][0]["to_world"][0][3] += offset
    for o in d["objects"]:
        o["to_world"] = [[1, 0, 0, offset], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    return d


def test_a_scene_far_from_the_origin_renders_as_at_the_origin():
    near = render(lit_sphere()).film
    far = render(moved(lit_sphere(), 1e5)).film
    a, b = near.combined(), far.combined()
    se = np.sqrt(near.variance_of_mean().sum()) / a.size
    assert abs(a.mean() - b.mean()) < 0.05 * se, (a.mean(), b.mean(), se)
    assert np.abs(a - b).mean() <= 1e-3 * a.mean()


def test_rebasing_moves_every_transform_by_the_camera_and_leaves_the_document_alone():
    far = moved(lit_sphere(), 1e5)
    original = copy.deepcopy(far)
    out = rebased(far)
    assert far == original                                    # not modified in place
    assert out["camera"]["to_world"][0][3] == pytest.approx(0.0, abs=1e-9)
    assert out["lights"][0]["to_world"][0][3] == pytest.approx(2.0, abs=1e-9)
    assert all(o["to_world"][0][3] == pytest.approx(0.0, abs=1e-9) for o in out["objects"])
    near = lit_sphere()
    assert rebased(near) is near                               # within REBASE_ABOVE: untouched
    near["camera"]["to_world"][0][3] = REBASE_ABOVE * 0.99
    assert rebased(near) is near
    bad = moved(lit_sphere(), 1e5)
    bad["objects"][0]["to_world"] = "not a matrix"            # left for validation to report
    assert rebased(bad) is bad
    with pytest.raises(Exception, match="to_world"):
        load_scene_data(bad, "scene.json")
