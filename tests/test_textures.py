"""Image-texture parameters: orientation, bilinear filtering, colour decoding, sanitising."""
import numpy as np
import OpenImageIO as oiio
import pytest

from backend.errors import SceneError
from backend.scene.reader import LoadContext
from backend.scene.reader import parse_param
from backend.textures import srgb_to_linear


def write_image(path, pixels, fmt=oiio.FLOAT):
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(w, h, c, fmt))
    assert out.write_image(np.ascontiguousarray(pixels if fmt == oiio.FLOAT else pixels.astype(np.uint8)))
    out.close()


def param(tmp_path, value, channels=3, lo=None, hi=None, color=None):
    ctx = LoadContext("scene.json", tmp_path)
    p = parse_param(value, "materials.m.color", ctx, channels, lo, hi, False,
                    color if color is not None else channels == 3)
    return p, ctx


def test_texture_orientation_and_bilinear_lookup(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.random((6, 8, 3)).astype(np.float32)
    write_image(tmp_path / "t.exr", img)
    p, _ = param(tmp_path, {"texture": "t.exr"})
    # Texel (row r, column c) centre is at u = (c + .5)/W, v = 1 − (r + .5)/H (v up, row 0 on top).
    r, c = 1, 5
    uv = np.array([[(c + 0.5) / 8, 1 - (r + 0.5) / 6]])
    assert np.allclose(p.bind(uv), img[r, c], atol=1e-6)
    # Halfway between two horizontally adjacent texel centres: their average.
    uv = np.array([[(c + 1.0) / 8, 1 - (r + 0.5) / 6]])
    assert np.allclose(p.bind(uv), 0.5 * (img[r, c] + img[r, c + 1]), atol=1e-6)
    # Repeat wrapping: u + 1 gives the same value.
    uv2 = np.array([[0.3, 0.7], [1.3, -0.3]])
    v = p.bind(uv2)
    assert np.allclose(v[0], v[1], atol=1e-6)


def test_8bit_colour_texture_is_srgb_decoded_but_scalar_params_are_not(tmp_path):
    img = np.full((2, 2, 3), 128, np.uint8)
    write_image(tmp_path / "t.png", img, oiio.UINT8)
    colour, _ = param(tmp_path, {"texture": "t.png"})
    assert np.allclose(colour.bind(np.array([[0.5, 0.5]])), srgb_to_linear(np.array(128 / 255)), atol=1e-4)
    rough, _ = param(tmp_path, {"texture": "t.png", "channel": 0}, channels=1, color=False)
    assert np.allclose(rough.bind(np.array([[0.5, 0.5]])), 128 / 255, atol=1e-4)
    forced, _ = param(tmp_path, {"texture": "t.png", "colorspace": "linear"})
    assert np.allclose(forced.bind(np.array([[0.5, 0.5]])), 128 / 255, atol=1e-4)


def test_a_colour_image_for_a_scalar_parameter_gives_its_rec709_luminance_exactly(tmp_path):
    """Luminance of a colour image read for a scalar (Rec.709 weights, linear data), rounded once
    from float64: grey texels keep their exact value, and colour ones are the correctly rounded
    weighted sums on every machine (a float32 product varied with the CPU's BLAS kernel)."""
    rng = np.random.default_rng(3)
    grey = (np.arange(16, dtype=np.float32) / 16)[None, :, None].repeat(3, axis=2)
    colour = rng.random((4, 16, 3)).astype(np.float32)
    img = np.concatenate([grey, colour], axis=0)
    write_image(tmp_path / "l.exr", img)
    p, _ = param(tmp_path, {"texture": "l.exr"}, channels=1, hi=1.0, color=False)
    t = p.texels[..., 0]
    assert np.array_equal(t[0], grey[0, :, 0])
    exact = colour.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    assert np.array_equal(t[1:], exact.astype(np.float32))


def test_nan_and_out_of_range_texels_are_sanitised_with_warnings(tmp_path):
    img = np.array([[[np.nan], [-1.0]], [[0.5], [7.0]]], np.float32)
    write_image(tmp_path / "r.exr", img)
    p, ctx = param(tmp_path, {"texture": "r.exr"}, channels=1, lo=0.0, hi=1.0, color=False)
    assert np.all(np.isfinite(p.texels)) and p.texels.min() >= 0 and p.texels.max() <= 1
    assert any("NaN/Inf texel" in w for w in ctx.warnings)
    assert any("below 0 clamped" in w for w in ctx.warnings)
    assert any("above 1 clamped" in w for w in ctx.warnings)


def test_constant_params_keep_constant_shapes(tmp_path):
    rgb, _ = param(tmp_path, [0.1, 0.2, 0.3])
    grey, _ = param(tmp_path, 0.4)
    s, _ = param(tmp_path, 0.25, channels=1)
    uv = np.zeros((10, 2))
    assert rgb.bind(uv).shape == (1, 3) and grey.bind(uv).shape == (1, 3)
    assert s.bind(uv).shape == ()


def strict_param(tmp_path, value):
    ctx = LoadContext("scene.json", tmp_path)
    ctx.missing_textures = "error"
    return parse_param(value, "materials.m.color", ctx, 3, None, None, False, True)


def test_bad_texture_specs(tmp_path):
    with pytest.raises(SceneError, match="materials.m.color.texture: texture file not found"):
        strict_param(tmp_path, {"texture": "missing.png"})
    (tmp_path / "junk.png").write_bytes(b"not an image")
    with pytest.raises(SceneError, match="materials.m.color.texture: cannot read image"):
        strict_param(tmp_path, {"texture": "junk.png"})
    with pytest.raises(SceneError, match="materials.m.color.colorspace: expected one of"):
        param(tmp_path, {"texture": "junk.png", "colorspace": "acescg"})


@pytest.mark.parametrize("name, content", [("missing.png", None), ("junk.png", b"not an image"),
                                           ("empty.exr", b"")])
def test_an_unreadable_texture_is_magenta_with_a_warning(tmp_path, name, content):
    # Cycles renders a missing image magenta and says so; a farm asks for an error instead.
    if content is not None:
        (tmp_path / name).write_bytes(content)
    p, ctx = param(tmp_path, {"texture": name})
    uv = np.array([[0.1, 0.2], [0.7, 0.9]])
    assert np.array_equal(p.bind(uv), [[1.0, 0.0, 1.0], [1.0, 0.0, 1.0]])
    assert len(ctx.warnings) == 1
    warning = ctx.warnings[0]
    assert warning.startswith("scene.json: materials.m.color.texture: ") and name in warning
    assert "rendered magenta" in warning and "--strict" in warning
    # A scalar parameter (roughness) reads the magenta's luminance, as any colour image's.
    s, _ = param(tmp_path, {"texture": name}, channels=1, lo=0.0, hi=1.0)
    assert np.allclose(s.bind(uv), 0.2126 + 0.0722)
