"""Normal and bump maps on the interfaces of a layered stack (``"normal"``, ``"normal_strength"``,
``"bump"`` on an interface; Blender's Normal Map and Bump nodes on a layer).

The plane of test_normal_maps (4 × 4 m, UVs [0, 1]², under a delta sun, seen straight down by an
orthographic camera, direct light only), with a stack: a null interface over an empty medium over
a Lambertian interface carrying the map. The walk has one path, and by the segment rule of
per-interface normals (Guo et al. §3: a segment along d that ends on an interface of normal n
weighs |⟨n, d⟩|/|cos d|) the pixel is albedo/π · E · ⟨n, sun⟩ · ⟨n, view⟩/cos(view), with the view
straight down: albedo/π · E · ⟨n, sun⟩ · n_z. The bump map's normal is the material-level closed
form of test_bump_maps: normalize(n − d · ∂h/∂x · X) for a height rising along u.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from render_util import assert_no_gain_in_white_furnace, render
from test_bump_maps import _ramp
from test_normal_maps import ALBEDO, TILTED, _expected, _plane_scene


def _stack(**detail) -> dict:
    return {"type": "layered",
            "interfaces": [{"type": "null"}, {"type": "diffuse", "color": [ALBEDO] * 3, **detail}],
            "media": [{"thickness": 1.0, "sigma_t": 0.0}]}


def _image(material: dict, uvs=None) -> np.ndarray:
    data = _plane_scene(material)
    if uvs is not None:
        data["meshes"]["plane"]["uvs"] = uvs
    return render(data).film.combined()[..., :3]


def _stack_expected(normal) -> float:
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    return _expected(n) * n[2]


def _mix(n, k):
    z = np.array([0.0, 0.0, 1.0])
    n = np.asarray(n, float) / np.linalg.norm(n)
    return z + k * (n - z)


def test_constant_interface_normal_and_its_strength():
    np.testing.assert_allclose(_image(_stack()), _stack_expected([0, 0, 1]), rtol=1e-5)
    np.testing.assert_allclose(_image(_stack(normal=TILTED)), _stack_expected(TILTED), rtol=1e-5)
    np.testing.assert_allclose(_image(_stack(normal=TILTED, normal_strength=0.5)),
                               _stack_expected(_mix(TILTED, 0.5)), rtol=1e-5)


def test_interface_normal_map_texture_with_strength(tmp_path):
    from backend.imageio import write_exr
    path = tmp_path / "normal.exr"
    write_exr(path, {"": np.broadcast_to((np.asarray(TILTED) + 1.0) / 2.0, (4, 4, 3)).astype(np.float32)})
    tex = {"texture": str(path)}
    np.testing.assert_allclose(_image(_stack(normal=tex)), _stack_expected(TILTED), rtol=1e-4)
    np.testing.assert_allclose(_image(_stack(normal=tex, normal_strength=0.3)),
                               _stack_expected(_mix(TILTED, 0.3)), rtol=1e-4)


def test_interface_bump_tilts_against_the_height_gradient(tmp_path):
    ramp = {"texture": _ramp(tmp_path, "u")}
    slope = 1.0 / 4.0                                   # ∂h/∂x per metre: 1 per UV unit over 4 m
    d = 4.0 * math.tan(math.radians(25))
    np.testing.assert_allclose(_image(_stack(bump={"height": ramp, "distance": d})),
                               _stack_expected([-d * slope, 0.0, 1.0]), rtol=1e-4)
    bumped = np.array([d * slope, 0.0, 1.0]) / math.hypot(d * slope, 1.0)
    np.testing.assert_allclose(
        _image(_stack(bump={"height": ramp, "distance": d, "invert": True, "strength": 0.4})),
        _stack_expected(_mix(bumped, 0.4)), rtol=1e-4)


def test_interface_bump_follows_the_uv_map_and_sits_on_the_normal_map(tmp_path):
    ramp = {"texture": _ramp(tmp_path, "v")}
    # UVs twice as dense: twice the slope per metre (rows away from the repeat seam at v = 1).
    img = _image(_stack(bump={"height": ramp, "distance": 1.0}), uvs=[[0, 0], [2, 0], [2, 2], [0, 2]])
    rows = np.r_[0:3, 13:16]
    np.testing.assert_allclose(img[rows], _stack_expected([0.0, -0.5, 1.0]), rtol=1e-4)
    # On top of a constant normal map: the gradient is taken against the mapped normal, as the
    # material's bump over a Normal Map (kernels/bump.py), so the result is n − d∇h with ∇h
    # perpendicular to the mapped normal n.
    n = np.asarray(TILTED)
    dpdv = np.array([0.0, 4.0, 0.0])               # dP/dv of the plane's UVs, dP/du = (4, 0, 0)
    dpdu = np.array([4.0, 0.0, 0.0])
    a, b = np.cross(dpdv, n), np.cross(n, dpdu)
    grad = (0.0 * a + 1.0 * b) / (dpdu @ a)         # ∂h/∂u = 0, ∂h/∂v = 1
    img = _image(_stack(normal=TILTED, bump={"height": ramp, "distance": 0.5}))
    np.testing.assert_allclose(img[rows], _stack_expected(n - 0.5 * grad), rtol=1e-4)


def test_interface_maps_are_refused_where_they_cannot_apply(tmp_path):
    from backend.errors import SceneError
    ramp = {"texture": _ramp(tmp_path, "u")}
    one = {"type": "layered", "interfaces": [{"type": "diffuse", "bump": {"height": ramp}}]}
    nested = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5},
                                                {"type": "layered", "interfaces": [{"type": "diffuse"}],
                                                 "normal_strength": 0.5}],
              "media": [{"sigma_t": 0.0}]}
    bad = _stack(bump={"height": ramp, "strength": 3.0})
    for material, words in ((one, "put the normal or bump map on the material"),
                            (nested, "on its own interfaces"), (bad, "strength")):
        with pytest.raises(SceneError) as err:
            _image(material)
        assert words in str(err.value) and "materials.m.interfaces[" in str(err.value), str(err.value)


def test_bumped_interfaces_create_no_energy_under_a_white_furnace(tmp_path):
    """A rough dielectric coat whose interface is strongly bumped, over a white Lambertian body
    with a bumped interface of its own: no gain beyond 4σ under a white world, no NaN."""
    from backend.imageio import write_exr
    rng = np.random.default_rng(11)
    path = tmp_path / "noise.exr"
    write_exr(path, {"": np.repeat(rng.uniform(0, 1, (32, 32, 1)).astype(np.float32), 3, axis=2)})
    bump = {"height": {"texture": str(path)}, "distance": 0.05}
    assert_no_gain_in_white_furnace({"type": "layered",
                                     "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.2, "bump": bump},
                                                    {"type": "diffuse", "color": [1, 1, 1], "bump": bump}],
                                     "media": [{"thickness": 0.5, "sigma_t": 0.3, "albedo": [1, 1, 1]}]})


def test_the_bsdf_inspector_reads_a_bumped_stack(tmp_path):
    """Without a surface the inspector reads bump maps over UVs along the frame's x and y (one
    unit per metre): the stack's eval equals that of the constant normal the ramp gives."""
    from backend.layered.probe import describe
    from layered_util import bind, load
    ramp = {"texture": _ramp(tmp_path, "u")}
    d = 0.3
    b = bind(load(_stack(bump={"height": ramp, "distance": d})), 1, uv=np.array([[0.5, 0.5]]))
    n = describe(b)["interfaces"][1]["normal"]
    np.testing.assert_allclose(n, np.array([-d, 0.0, 1.0]) / math.hypot(d, 1.0), rtol=1e-9)
