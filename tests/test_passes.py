"""Data passes (backend/passes.py) against closed forms: a camera facing planes at known places.

Cycles' conventions (measured with Blender 5.0.1; the Blender-side comparison is
tests/blender/test_passes_parity.py): Depth = distance along the view axis, 1e10 where sample 0
hit nothing; Position and Object/Material Index from sample 0 too (never a mix); Mist, Normal,
UV averaged over the samples (escaped: Mist 1, the others 0); Normal turned towards the camera.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from backend.errors import SceneError
from backend.passes import DEPTH_ESCAPED
from render_util import front_perspective, look_down_ortho, render, scene

ALL = {"depth": {}, "mist": {"start": 2.0, "depth": 10.0, "falloff": "linear"}, "normal": {},
       "position": {}, "uv": {}, "object_index": {}, "material_index": {}}
DISTANCE = 5.0           # camera on −Y at this distance from the plane y = 0 [m]
HALF = 0.3               # half-width of the image plane at 1 m: the view spans ±1.5 m at the plane


def _rect_facing_camera(size, y, flip=False):
    """A rectangle in the plane y = const, normal −Y (towards the camera) unless ``flip``,
    UV (x + size/2) / size, (z + size/2) / size."""
    h = size / 2
    pos = [[-h, y, -h], [h, y, -h], [h, y, h], [-h, y, h]]
    idx = [[0, 2, 1], [0, 3, 2]] if not flip else [[0, 1, 2], [0, 2, 3]]
    uv = [[0, 0], [1, 0], [1, 1], [0, 1]]
    return {"positions": pos, "indices": idx, "uvs": uv}


def _scene(passes, objects=None, width=24, height=24, camera=None, spp=4):
    meshes = {"wall": _rect_facing_camera(2.0, 0.0)}
    objects = objects or [{"mesh": "wall", "materials": ["grey"], "pass_index": 7}]
    return scene(width, height, camera or front_perspective(DISTANCE, HALF),
                 {"grey": {"type": "diffuse", "color": [0.5, 0.5, 0.5], "pass_index": 3}},
                 meshes, objects, world={"type": "constant", "color": [0.1, 0.1, 0.1]},
                 render={"spp": spp, "seed": 3, "max_bounces": 0}) | {"passes": passes}


def _pixel_rays(width, height, cam):
    """World point where each pixel centre's ray meets the plane y = 0 (perspective camera on −Y)."""
    ys, xs = np.mgrid[0:height, 0:width]
    s = (xs + 0.5) / width
    t = (ys + 0.5) / height
    x = (2 * s - 1) * HALF * DISTANCE
    z = (1 - 2 * t) * HALF * DISTANCE
    return x, z


def test_every_pass_matches_closed_forms():
    res = render(_scene(ALL, spp=16))
    img = res.film.pass_images()
    assert list(img) == ["Depth", "Position", "Object Index", "Material Index", "Mist", "Normal", "UV"]
    w = h = 24
    x, z = _pixel_rays(w, h, None)
    # The wall covers |x|, |z| ≤ 1 m; the view ±1.5 m: pixels whose whole filter footprint
    # (Blackman-Harris, ±1.5 px = ±0.19 m) lies on the wall, or off it.
    px = 2 * HALF * DISTANCE / w
    inside = (np.abs(x) < 1 - 2 * px) & (np.abs(z) < 1 - 2 * px)
    outside = (np.abs(x) > 1 + 2 * px) | (np.abs(z) > 1 + 2 * px)
    assert inside.sum() > 100 and outside.sum() > 100
    depth = img["Depth"][..., 0]
    np.testing.assert_allclose(depth[inside], DISTANCE, rtol=1e-6)        # view-axis distance
    assert np.all(depth[outside] == DEPTH_ESCAPED)
    np.testing.assert_array_equal(img["Object Index"][..., 0][inside], 7)
    np.testing.assert_array_equal(img["Material Index"][..., 0][inside], 3)
    assert np.all(img["Object Index"][..., 0][outside] == 0)
    # Mist: Euclidean distance, linear falloff from 2 m over 10 m, averaged over the pixel's
    # samples (a sample's offset moves the distance by < 1e-3 relative here); escaped → 1.
    r = np.sqrt(DISTANCE ** 2 + x ** 2 + z ** 2)
    np.testing.assert_allclose(img["Mist"][..., 0][inside], ((r - 2) / 10)[inside], atol=2e-3)
    assert np.all(img["Mist"][..., 0][outside] == 1.0)
    # Normal towards the camera, world space; Position on the wall; UV with its third channel 1.
    np.testing.assert_allclose(img["Normal"][inside], np.broadcast_to([0, -1, 0], img["Normal"][inside].shape), atol=1e-6)
    pos = img["Position"]
    # Sample 0's hit: within the filter's support (±1.5 px) of the pixel centre's ray.
    assert np.all(np.abs(pos[..., 0][inside] - x[inside]) < 1.5 * px)
    assert np.all(np.abs(pos[..., 2][inside] - z[inside]) < 1.5 * px)
    np.testing.assert_allclose(pos[..., 1][inside], 0.0, atol=1e-6)
    uv = img["UV"]
    assert np.all(np.abs(uv[..., 0][inside] - (x[inside] + 1) / 2) < 0.5 * px / 2)
    assert np.all(np.abs(uv[..., 1][inside] - (z[inside] + 1) / 2) < 0.5 * px / 2)
    np.testing.assert_array_equal(uv[..., 2][inside], 1.0)
    for name in ("Normal", "Position", "UV"):
        assert np.all(img[name][outside] == 0.0), name


def test_first_sample_passes_never_mix_and_averaged_passes_do():
    """Two walls at different depths and indices meet in the middle of the image: Depth,
    Position and the indices of an edge pixel are one wall's (sample 0); UV (only the far wall
    has a UV map) is an average: its third channel is the UV-mapped fraction of the samples."""
    near = {"mesh": "near", "materials": ["grey"], "pass_index": 1}
    far = {"mesh": "far", "materials": ["grey"], "pass_index": 2}
    data = _scene({"depth": {}, "object_index": {}, "position": {}, "uv": {}}, objects=[near, far], spp=32)
    data["meshes"] = {"near": {"positions": [[-3, -1, -3], [0, -1, -3], [0, -1, 3], [-3, -1, 3]],
                               "indices": [[0, 2, 1], [0, 3, 2]]},
                      "far": {"positions": [[0, 0, -3], [3, 0, -3], [3, 0, 3], [0, 0, 3]],
                              "indices": [[0, 2, 1], [0, 3, 2]], "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]]}}
    img = render(data).film.pass_images()
    depth, index = img["Depth"][..., 0], img["Object Index"][..., 0]
    assert set(np.unique(depth)) <= {4.0, 5.0} and set(np.unique(index)) == {1.0, 2.0}
    assert np.all((depth == 4.0) == (index == 1.0))          # one sample's hit, both passes
    y = img["Position"][..., 1]
    assert np.all((y == -1.0) == (index == 1.0)) and np.all((y == 0.0) == (index == 2.0))
    a = img["UV"][..., 2]
    assert np.any((a > 0.01) & (a < 0.99))


def test_back_face_normal_faces_the_camera_and_orthographic_depth():
    data = _scene({"normal": {}, "depth": {}, "mist": {"start": 0.0, "depth": 20.0}},
                  camera=look_down_ortho(0.5, height=4.0))
    data["meshes"] = {"wall": {"positions": [[-2, -2, 1], [2, -2, 1], [2, 2, 1], [-2, 2, 1]],
                               "indices": [[0, 2, 1], [0, 3, 2]]}}     # normal −Z: seen from behind
    film = render(data).film
    img = film.pass_images()
    np.testing.assert_allclose(img["Normal"], np.broadcast_to([0, 0, 1], img["Normal"].shape), atol=1e-6)
    # The denoiser's normal (Denoising Normal) faces the camera too, as the Normal pass does.
    np.testing.assert_allclose(film.normal_image(), np.broadcast_to([0, 0, 1], img["Normal"].shape), atol=1e-6)
    np.testing.assert_allclose(img["Depth"], 3.0, rtol=1e-6)              # 4 m camera, plane z = 1
    # Orthographic mist: along the view axis, quadratic (Blender's default) from 0 over 20 m.
    np.testing.assert_allclose(img["Mist"], (3.0 / 20.0) ** 2, rtol=1e-6)


def test_position_adds_back_the_rebase_offset():
    """A scene 10 km from the origin is traced around the camera (scene loader ``rebased``);
    Position is still in the file's world space."""
    data = _scene({"position": {}})
    off = np.array([1.0e4, 2.0e4, -3.0e3])
    data["camera"]["to_world"] = (np.array(data["camera"]["to_world"], float)
                                  + np.pad(off[:, None], ((0, 1), (3, 0)))).tolist()
    data["objects"][0]["to_world"] = [[1, 0, 0, off[0]], [0, 1, 0, off[1]], [0, 0, 1, off[2]], [0, 0, 0, 1]]
    res = render(data)
    pos = res.film.pass_images()["Position"]
    centre = pos[10:14, 10:14].reshape(-1, 3)
    np.testing.assert_allclose(centre.mean(axis=0), off, atol=0.05)


def test_no_pass_requested_allocates_nothing():
    data = _scene({})
    del data["passes"]
    res = render(data)
    assert res.film.pass_images() == {}
    assert res.film.first.size == 0 and res.film.pass_sum.size == 0
    from backend.geometry.accel import Accelerator
    from backend.integrator import PathTracer
    from backend.scene.loader import load_scene_data
    sc = load_scene_data(data, "<test>")
    out = PathTracer(sc, Accelerator(sc.soup)).render(np.arange(4, dtype=np.int64), 2, None)
    assert "passes" not in out


@pytest.mark.parametrize("passes, message", [
    ({"vector": {}}, "passes.vector: unknown pass 'vector'"),
    ({"mist": {"falloff": "cubic"}}, "passes.mist.falloff: expected one of"),
    ({"mist": {"depth": -1}}, "passes.mist.depth"),
    ({"depth": {"x": 1}}, "passes.depth.x: unknown field"),
])
def test_bad_passes_are_named(passes, message):
    from backend.scene.loader import load_scene_data
    with pytest.raises(SceneError, match=message.replace(".", r"\.").replace("(", r"\(")):
        load_scene_data(_scene(passes), "<test>")


def test_bad_pass_index_is_named():
    from backend.scene.loader import load_scene_data
    data = _scene({"object_index": {}})
    data["objects"][0]["pass_index"] = -2
    with pytest.raises(SceneError, match=r"objects\[0\]\.pass_index"):
        load_scene_data(data, "<test>")


def test_exr_holds_the_passes_with_blender_channel_names(tmp_path):
    from backend.imageio import read_exr
    from backend.cli.render_one import write_outputs
    res = render(_scene({"depth": {}, "uv": {}, "material_index": {}}))
    write_outputs(res, tmp_path / "out.exr", None)
    pixels, names = read_exr(tmp_path / "out.exr")
    for want in ("Depth.Z", "Material Index.X", "UV.U", "UV.V", "UV.A"):
        assert want in names
    assert "Mist.Z" not in names
    depth = pixels[:, :, names.index("Depth.Z")]
    assert depth[12, 12] == pytest.approx(DISTANCE) and depth[0, 0] == pytest.approx(DEPTH_ESCAPED)


def test_named_view_renders_its_own_camera():
    """``views`` + RenderOptions.view (the CLI's --view): the view's camera renders, not
    ``camera``; an unknown view is one clear error."""
    from backend.errors import LaminaError
    data = _scene({"depth": {}})
    shifted = dict(front_perspective(DISTANCE + 1.0, HALF))
    data["views"] = {"left": front_perspective(DISTANCE, HALF), "far": shifted}
    img = render(data, view="far").film.pass_images()
    assert img["Depth"][12, 12, 0] == pytest.approx(DISTANCE + 1.0)
    with pytest.raises(LaminaError, match="no such view"):
        render(data, view="right")
    assert math.isfinite(render(data).film.pass_images()["Depth"][12, 12, 0])


def _addon_module(name):
    """An add-on module without bpy, loaded from its file (its package imports bpy)."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "addon" / "export" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"_lamina_addon_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_add_on_renders_exactly_the_backend_passes_and_warns_about_the_rest():
    from backend.passes import PASSES
    rendered = _addon_module("passes").RENDERED
    unsupported = _addon_module("unsupported").PASSES
    assert sorted(name for _, name, _, _, _ in rendered) == sorted(PASSES)
    # Blender names and channels as the backend writes them (one definition each side).
    assert {label: chans for _, _, label, chans, _ in rendered} == {v[2]: v[3] for v in PASSES.values()}
    switches = {prop for prop, *_ in rendered}
    assert not switches & {prop for prop, _ in unsupported}, "a rendered pass is still warned about"
    assert {"use_pass_vector", "use_pass_ambient_occlusion", "use_pass_emit"} <= {p for p, _ in unsupported}
