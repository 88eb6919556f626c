"""One-sided emission (``"emission_sides": "front"``) against two-sided emission and closed forms.

A square emitter hangs above a diffuse floor, seen from above by an orthographic camera. From
its front a one-sided emitter looks exactly like a two-sided one (radiance L on the emitter's
pixels) and the side it does not face is dark; from its back it is black and lights, through its
front, what its front faces exactly as the two-sided one does (next-event estimation with the
per-triangle sidedness and BSDF-sampled hits with the MIS weight of the same density).
"""
import numpy as np
import pytest

from render_util import look_down_ortho, render, scene

K_SIGMA = 4.0
L = 3.0
SIZE = 32
HALF = 1.0


def emitter_scene(sides: str | None, facing: str, material_type: str = "emission"):
    h = 0.3
    up = [[-h, -h, 1.0], [h, -h, 1.0], [h, h, 1.0], [-h, h, 1.0]]       # counter-clockwise from above
    indices = [[0, 1, 2], [0, 2, 3]] if facing == "up" else [[0, 2, 1], [0, 3, 2]]
    glow = ({"type": "emission", "color": [L, L, L], "strength": 1.0} if material_type == "emission"
            else {"type": "diffuse", "color": [0.0, 0.0, 0.0], "emission": [L, L, L]})
    if sides is not None:
        glow["emission_sides"] = sides
    return scene(SIZE, SIZE, look_down_ortho(HALF),
                 {"floor": {"type": "diffuse", "color": 0.5}, "glow": glow},
                 {"floor": {"shape": "rectangle", "size": [2 * HALF, 2 * HALF]},
                  "emitter": {"positions": up, "indices": indices}},
                 [{"mesh": "floor", "materials": ["floor"]}, {"mesh": "emitter", "materials": ["glow"]}],
                 render={"spp": 64, "max_bounces": 0, "seed": 5},
                 film_filter={"type": "box", "width": 1.0})


def masks():
    c = ((np.arange(SIZE) + 0.5) / SIZE * 2 - 1) * HALF
    x, y = np.meshgrid(c, -c)
    pix = 2 * HALF / SIZE
    on = (np.abs(x) < 0.3 - pix) & (np.abs(y) < 0.3 - pix)          # pixels wholly on the emitter
    floor = (np.abs(x) > 0.3 + pix) | (np.abs(y) > 0.3 + pix)        # pixels wholly on the floor
    return on, floor


@pytest.mark.parametrize("material_type", ["emission", "diffuse"])
def test_one_sided_emitter_front_back_and_two_sided(material_type):
    on, floor = masks()
    runs = {}
    for sides in (None, "front"):
        for facing in ("up", "down"):
            res = render(emitter_scene(sides, facing, material_type))
            runs[sides, facing] = (res.film.combined(), res.film.variance_of_mean())
    two_up, _ = runs[None, "up"]
    # Seen from the front (the camera is above an up-facing emitter): radiance L, one- or two-sided.
    np.testing.assert_allclose(runs["front", "up"][0][on], L, rtol=1e-5)
    np.testing.assert_allclose(two_up[on], L, rtol=1e-5)
    np.testing.assert_allclose(runs[None, "down"][0][on], L, rtol=1e-5)
    # Seen from the back: black.
    assert np.all(runs["front", "down"][0][on] == 0.0)
    # The floor: an up-facing one-sided emitter sends nothing down ...
    assert np.all(runs["front", "up"][0][floor] == 0.0)
    # ... a down-facing one lights it as the two-sided one does (within Monte Carlo error).
    a, va = runs["front", "down"]
    b, vb = runs[None, "down"]
    sa, sb = a[floor].sum(axis=0), b[floor].sum(axis=0)
    se = np.sqrt(va[floor].sum(axis=0) + vb[floor].sum(axis=0))
    assert sb[0] > 0.0
    assert np.all(np.abs(sa - sb) <= K_SIGMA * se + 1e-9 * sb), (sa, sb, se)
    # and the two-sided emitter lights the floor the same whichever way it faces.
    c, vc = runs[None, "up"]
    sc_ = c[floor].sum(axis=0)
    se2 = np.sqrt(vc[floor].sum(axis=0) + vb[floor].sum(axis=0))
    assert np.all(np.abs(sc_ - sb) <= K_SIGMA * se2), (sc_, sb, se2)


def test_emission_sides_is_validated_and_warned():
    from backend.errors import SceneError
    from backend.scene.loader import load_scene_data
    data = emitter_scene("sideways", "up")
    with pytest.raises(SceneError, match="emission_sides"):
        load_scene_data(data, "<test>")
    data = emitter_scene(None, "up")
    data["materials"]["floor"]["emission_sides"] = "front"        # a material that emits nothing
    sc = load_scene_data(data, "<test>")
    assert any("emission_sides" in w and "emits nothing" in w for w in sc.warnings)


def test_mesh_light_power_counts_sides():
    from backend.lights.mesh import MeshLight
    tris = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[2, 0, 0], [3, 0, 0], [2, 1, 0]]], float)
    rad = np.ones((2, 3))
    one = MeshLight(tris, rad, two_sided=False).power()
    both = MeshLight(tris, rad, two_sided=True).power()
    mixed = MeshLight(tris, rad, two_sided=[True, False]).power()
    assert both == pytest.approx(2 * one) and mixed == pytest.approx(1.5 * one)
