"""Bump maps (``"bump"`` on any material; Blender's Bump node) against closed forms.

The Lambertian plane of test_normal_maps (4 × 4 m, UVs [0, 1]², so dP/du = 4 m along +X and
dP/dv = 4 m along +Y) under a delta sun, direct light only: every pixel is albedo/π · E · cos
between the bumped normal and the sun. A height image that rises linearly across its texels has,
between texel centres, the constant slope ∂h/∂u = (rise per texel) × width, so the bumped normal is
normalize(n − d · (∂h/∂u / 4 m) · X) everywhere the camera sees (u in [0.25, 0.75], away from the
repeat seam).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from render_util import assert_no_gain_in_white_furnace, render
from test_normal_maps import ALBEDO, _expected, _plane_scene

W = 16                        # texels across the ramp


def _ramp(tmp_path, along: str, name: str = "ramp.exr") -> str:
    """A height image rising by 1/W per texel along image x ("u") or image up ("v"):
    ∂h/∂u (or ∂h/∂v) = 1 per unit of UV."""
    from backend.imageio import write_exr
    i = np.arange(W, dtype=np.float32) / W
    img = np.broadcast_to(i[None, :], (W, W)) if along == "u" else np.broadcast_to(i[::-1, None], (W, W))
    path = tmp_path / name
    write_exr(path, {"": np.repeat(img[..., None], 3, axis=2).astype(np.float32)})
    return str(path)


def _image(material: dict) -> np.ndarray:
    return render(_plane_scene(material)).film.combined()[..., :3]


def _diffuse(**extra) -> dict:
    return {"type": "diffuse", "color": [ALBEDO] * 3, **extra}


def test_height_rising_along_u_tilts_the_normal_against_its_gradient(tmp_path):
    ramp = _ramp(tmp_path, "u")
    slope = 1.0 / 4.0                                   # ∂h/∂x in height units per metre
    d = 4.0 * math.tan(math.radians(25))                # d · slope = tan 25°
    # Rising towards +X: the normal leans towards −X (away from the sun at +X: darker).
    np.testing.assert_allclose(_image(_diffuse(bump={"height": {"texture": ramp}, "distance": d})),
                               _expected([-d * slope, 0.0, 1.0]), rtol=1e-4)
    # Inverted: towards +X, cos 15° instead of cos 40°.
    inverted = _image(_diffuse(bump={"height": {"texture": ramp}, "distance": d, "invert": True}))
    np.testing.assert_allclose(inverted, _expected([d * slope, 0.0, 1.0]), rtol=1e-4)
    # Strength mixes as Cycles: normalize(n + k · (bumped − n)).
    bumped = np.array([d * slope, 0.0, 1.0]) / math.hypot(d * slope, 1.0)
    mixed = np.array([0.0, 0.0, 1.0]) + 0.4 * (bumped - [0.0, 0.0, 1.0])
    np.testing.assert_allclose(
        _image(_diffuse(bump={"height": {"texture": ramp}, "distance": d, "invert": True, "strength": 0.4})),
        _expected(mixed), rtol=1e-4)


def test_height_rising_along_v_tilts_towards_minus_y_and_scales_with_the_uv_map(tmp_path):
    ramp = _ramp(tmp_path, "v")
    d = 1.0
    # The sun lies in the XZ plane: a tilt towards −Y only shortens cos by the tilt's cosine.
    # (Tilts stay below 45°: beyond, the view's mirror direction would fall below the surface
    # and the normal is bent back, as in Cycles.)
    np.testing.assert_allclose(_image(_diffuse(bump={"height": {"texture": ramp}, "distance": d})),
                               _expected([0.0, -d / 4.0, 1.0]), rtol=1e-4)
    # The same texture over UVs twice as dense (u, v in [0, 2]): twice the slope per metre.
    data = _plane_scene(_diffuse(bump={"height": {"texture": ramp}, "distance": d}))
    data["meshes"]["plane"]["uvs"] = [[0, 0], [2, 0], [2, 2], [0, 2]]
    img = render(data).film.combined()[..., :3]
    # u, v in [0.5, 1.5]: away from the seam at 1 only where v is not within half a texel of it.
    rows = np.r_[0:3, 13:16]                           # the image rows far from v = 1
    np.testing.assert_allclose(img[rows], _expected([0.0, -d / 2.0, 1.0]), rtol=1e-4)


def test_a_constant_height_or_zero_distance_changes_nothing(tmp_path):
    plain = _image(_diffuse())
    np.testing.assert_allclose(_image(_diffuse(bump={"height": 0.7, "distance": 3.0})), plain, rtol=0)
    ramp = _ramp(tmp_path, "u")
    np.testing.assert_allclose(_image(_diffuse(bump={"height": {"texture": ramp}, "distance": 0.0})), plain, rtol=0)


def test_bad_bump_fields_are_refused_with_their_path(tmp_path):
    from backend.errors import SceneError
    for bump, words in (({"height": 0.5, "strength": 2.0}, "strength"), ({"height": 0.5, "invert": "yes"}, "invert"),
                        ({"height": 0.5, "distance": 1.0, "size": 3}, "size"), (0.5, "bump")):
        with pytest.raises(SceneError) as err:
            _image(_diffuse(bump=bump))
        assert "materials.m.bump" in str(err.value) and words in str(err.value), str(err.value)


@pytest.mark.parametrize("material", [
    {"type": "conductor", "metal": "Ag", "roughness": 0.3},
    {"type": "conductor", "metal": "Ag", "roughness": 0.0},
    {"type": "dielectric", "ior": 1.5, "roughness": 0.2},
], ids=["rough-silver", "mirror", "rough-glass"])
def test_bumped_materials_create_no_energy_under_a_white_furnace(tmp_path, material):
    """A strong random bump on a closed sphere under a constant white world: no pixel above the
    world's radiance by more than 4σ (σ from the pixel's own sample variance), no NaN."""
    from backend.imageio import write_exr
    rng = np.random.default_rng(7)
    height = rng.uniform(0, 1, (32, 32)).astype(np.float32)
    path = tmp_path / "noise.exr"
    write_exr(path, {"": np.repeat(height[..., None], 3, axis=2)})
    assert_no_gain_in_white_furnace(dict(material, bump={"height": {"texture": str(path)}, "distance": 0.05}))
