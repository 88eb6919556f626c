"""Ray visibility, light linking and shadow linking in the backend, against closed forms: a
point light of power P at height h over a Lambertian floor of albedo ρ, direct light only
(max_bounces 0), seen from straight above, gives L = ρ/π · P/(4π) · h / r³ at a floor point at
distance r from the light. A blocker that must not count (invisible to shadow rays, not one of
the light's blockers, hidden from the camera) leaves exactly that; a light that must not light
the floor leaves exactly 0. (Comparison with Cycles: tests/blender/test_visibility_parity.py.)"""
from __future__ import annotations

import copy

import numpy as np
import pytest

from backend.errors import SceneError
from backend.scene.loader import load_scene_data
from render_util import IDENTITY, look_down_ortho, render, scene

H = 2.0           # light height [m]
P = 100.0         # light power [W]
RHO = 0.5
HALF = 1.0        # the camera sees [-HALF, HALF]² of the floor
N = 24            # pixels a side
K = 4.0           # standard errors


def _move(x, y, z, s=1.0):
    return [[s, 0, 0, x], [0, s, 0, y], [0, 0, s, z], [0, 0, 0, 1]]


def _scene(blocker=None, light_extra=None, floor_extra=None, spp=16):
    """Floor, an optional 1 m blocker 1 m above the origin (hidden from the camera unless
    ``blocker`` says otherwise), a point light H above the origin."""
    objects = [dict({"name": "Floor", "mesh": "floor", "to_world": IDENTITY, "materials": ["floor"]},
                    **(floor_extra or {}))]
    if blocker is not None:
        objects.append(dict({"name": "Blocker", "mesh": "square", "to_world": _move(0, 0, 1.0),
                             "materials": ["floor"], "visible_camera": False}, **blocker))
    light = dict({"type": "point", "to_world": _move(0, 0, H), "power": P}, **(light_extra or {}))
    return scene(N, N, look_down_ortho(HALF, 5.0),
                 {"floor": {"type": "diffuse", "color": [RHO] * 3}},
                 {"floor": {"shape": "rectangle", "size": [4, 4]}, "square": {"shape": "rectangle", "size": [1, 1]}},
                 objects, [light], render={"spp": spp, "max_bounces": 0, "seed": 3},
                 film_filter={"type": "box", "width": 1})


def _closed_form():
    """The expected pixel values: the closed form averaged over each pixel (8×8 points)."""
    sub = (np.arange(N * 8) + 0.5) / (N * 8) * 2 * HALF - HALF
    x, y = np.meshgrid(sub, -sub)                      # image row 0 = +Y
    r = np.sqrt(x * x + y * y + H * H)
    L = RHO / np.pi * P / (4 * np.pi) * H / r ** 3
    return L.reshape(N, 8, N, 8).mean(axis=(1, 3))


def _image(data):
    res = render(data)
    return res.film.combined()[..., 0], res.film.variance_of_mean()[..., 0]


def _shadow_box():
    """Pixels inside the blocker's shadow (the 1 m square 1 m up, light 2 m up: a 2 m shadow,
    i.e. the whole view); a margin keeps the comparison off the edges."""
    return np.s_[2:-2, 2:-2]


def assert_closed_form(img, var):
    want = _closed_form()
    box = _shadow_box()
    diff = (img[box] - want[box]).mean()
    se = np.sqrt(var[box].sum()) / img[box].size + 1e-12
    assert abs(diff) <= K * se + 1e-6 * want[box].mean(), (diff, se, want[box].mean())


def test_unblocked_floor_matches_the_closed_form():
    assert_closed_form(*_image(_scene()))


def test_a_blocker_casts_its_shadow():
    img, _ = _image(_scene(blocker={}))
    assert img[_shadow_box()].max() == 0.0


def test_an_object_invisible_to_shadow_rays_casts_none():
    assert_closed_form(*_image(_scene(blocker={"visible_shadow": False})))


def test_an_object_hidden_from_the_camera_shows_what_is_behind_it():
    """The camera ray is traced again past the hidden object (which still casts its shadow:
    visible_shadow false here, so the floor behind it is lit)."""
    img, var = _image(_scene(blocker={"visible_shadow": False, "visible_camera": False}))
    assert_closed_form(img, var)


@pytest.mark.parametrize("lists, lit", [({"exclude": ["Floor"]}, False), ({"include": ["Floor"]}, True),
                                        ({"include": ["Blocker"]}, False), ({"include": []}, False),
                                        ({"exclude": ["Blocker"]}, True)])
def test_light_linking(lists, lit):
    img, var = _image(_scene(blocker={"visible_shadow": False},
                             light_extra={"light_linking": {"receivers": lists}}))
    if lit:
        assert_closed_form(img, var)
    else:
        assert img.max() == 0.0


@pytest.mark.parametrize("lists, blocked", [({"exclude": ["Blocker"]}, False), ({"include": ["Blocker"]}, True),
                                            ({"include": ["Floor"]}, False), ({"include": []}, False)])
def test_shadow_linking(lists, blocked):
    img, var = _image(_scene(blocker={}, light_extra={"light_linking": {"blockers": lists}}))
    if blocked:
        assert img[_shadow_box()].max() == 0.0
    else:
        assert_closed_form(img, var)


def test_an_emitter_hidden_from_diffuse_rays_lights_no_diffuse_surface():
    """An emissive square facing the floor, invisible to diffuse rays: neither next-event
    estimation nor the floor's diffuse bounces find it (Cycles' SHADER_EXCLUDE_DIFFUSE)."""
    data = _scene(spp=8)
    data["lights"] = []
    data["materials"]["glow"] = {"type": "diffuse", "color": [0, 0, 0], "emission": [5, 5, 5]}
    flip = [[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 1.0], [0, 0, 0, 1]]
    data["objects"].append({"name": "Glow", "mesh": "square", "to_world": flip, "materials": ["glow"],
                            "visible_camera": False, "visible_diffuse": False})
    data["render"]["max_bounces"] = 2
    img, _ = _image(data)
    assert img.max() == 0.0
    data["objects"][-1]["visible_diffuse"] = True
    img, _ = _image(data)
    assert img[_shadow_box()].min() > 0.1


@pytest.mark.parametrize("light_linking, message", [
    ({"receivers": {"include": ["Nobody"]}}, "lights[0].light_linking.receivers.include[0]: unknown object 'Nobody'"),
    ({"receivers": {"include": [3]}}, "lights[0].light_linking.receivers.include[0]: expected an object name"),
    ({"receivers": {"only": []}}, "lights[0].light_linking.receivers.only: unknown field"),
    ({"blocked": {}}, "lights[0].light_linking.blocked: unknown field"),
])
def test_bad_linking_is_a_clear_error(light_linking, message):
    data = _scene(light_extra={"light_linking": light_linking})
    with pytest.raises(SceneError) as info:
        load_scene_data(copy.deepcopy(data), "<test>")
    assert message in str(info.value)


def test_objects_take_no_blockers():
    """Shadow linking of an emissive object is not rendered: refused, not ignored."""
    data = _scene(floor_extra={"light_linking": {"blockers": {"include": ["Floor"]}}})
    with pytest.raises(SceneError) as info:
        load_scene_data(copy.deepcopy(data), "<test>")
    assert "objects[0].light_linking.blockers: unknown field" in str(info.value)


def test_layered_stacks_reflect_as_diffuse_when_they_hold_a_diffuse_layer():
    from backend.materials import load_all
    from backend.scene.reader import LoadContext, Node, dispatch
    from backend.visibility import _has_diffuse
    ctx = LoadContext("<t>")

    def material(interfaces):
        return dispatch(Node({"type": "layered", "interfaces": interfaces,
                              "media": [{"thickness": 0.0}] * (len(interfaces) - 1)}, "m", ctx), load_all())
    coat = {"type": "dielectric", "ior": 1.5, "roughness": 0.1}
    assert _has_diffuse(material([coat, {"type": "diffuse", "color": [0.5, 0.5, 0.5]}]))
    assert not _has_diffuse(material([coat, {"type": "conductor", "metal": "Au", "roughness": 0.2}]))
