"""Texturable parameters: a constant or an image texture looked up by UV (bilinear, repeat).

Bound values follow the shapes that ``materials.base.lanes`` understands:
scalar params give shape () when constant and (n,) when textured; RGB params give (1, 3) when
constant and (n, 3) when textured. Constants are never expanded to per-lane arrays
("constants are not textures": no work for what a scene does not use).

Images are read with OpenImageIO as float32. Colour-space: 8/16-bit images used for colour
parameters are sRGB-decoded unless the file says otherwise; float images (EXR/HDR) and non-colour
parameters (roughness, density, ...) are used as stored. NaN/Inf texels become 0 and out-of-range
texels are clamped to the parameter's range, each with one warning (never NaN in the renderer).
UV convention: Blender's (u right, v up, (0, 0) = bottom-left of the image).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .errors import SceneError


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    c = np.clip(c, 0.0, None)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


def read_image(path: Path, where: str = "", field: str = "") -> tuple[np.ndarray, bool]:
    """Read an image as float32 (H, W, C). Returns (pixels, is_float_format). Raises SceneError
    (never an OSError or an OpenImageIO exception): a missing, unreadable, truncated or
    too-large image is an error naming ``field``."""
    from .limits import available_memory, short
    try:
        import OpenImageIO as oiio
    except ImportError as exc:  # pragma: no cover - dependency is pinned
        raise SceneError(where, field, f"OpenImageIO is not installed ({exc})") from exc
    try:
        exists = Path(path).is_file()
    except (OSError, ValueError) as exc:
        raise SceneError(where, field, f"cannot use image {short(path, 200)}: "
                                       f"{getattr(exc, 'strerror', None) or exc}") from None
    if not exists:
        raise SceneError(where, field, f"texture file not found: {short(path, 200)}")
    try:
        inp = oiio.ImageInput.open(str(path))
    except Exception as exc:  # noqa: BLE001 - OpenImageIO raises various types
        raise SceneError(where, field, f"cannot read image {short(path, 200)}: {short(exc, 200)}") from None
    if inp is None:
        raise SceneError(where, field, f"cannot read image {short(path, 200)}: {short(oiio.geterror(), 200)}")
    try:
        spec = inp.spec()
        need = int(spec.width) * int(spec.height) * max(int(spec.nchannels), 1) * 4
        have = available_memory()
        if spec.width <= 0 or spec.height <= 0 or spec.nchannels <= 0:
            raise SceneError(where, field, f"cannot read image {short(path, 200)}: it has no pixels "
                                           f"({spec.width} × {spec.height}, {spec.nchannels} channels)")
        if have is not None and need > have // 2:
            raise SceneError(where, field, f"image {short(path, 200)} is too large: {spec.width} × "
                                           f"{spec.height} × {spec.nchannels} channels need "
                                           f"{need / 2 ** 30:.1f} GiB, {have / 2 ** 30:.1f} GiB available")
        try:
            pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        except Exception as exc:  # noqa: BLE001
            raise SceneError(where, field, f"cannot decode image {short(path, 200)}: {short(exc, 200)}") from None
        if pixels is None:
            raise SceneError(where, field, f"cannot decode image {short(path, 200)}: {short(inp.geterror(), 200)}")
        fmt = str(spec.format)
        is_float = fmt in ("float", "half", "double")
        colorspace = spec.get_string_attribute("oiio:ColorSpace", "")
    finally:
        inp.close()
    pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    if colorspace.lower() in ("linear", "lin_rec709", "scene_linear"):
        is_float = True
    return pixels, is_float


class Param:
    """A bindable parameter. ``bind(uv)`` returns the per-lane value (see module docstring)."""

    channels: int = 1
    is_constant: bool = True

    def bind(self, uv: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def mean(self) -> np.ndarray:
        """Average value (scalar or (3,)), e.g. for light power estimates."""
        raise NotImplementedError

    def kernel_pack(self, packer, channels: int, factor) -> tuple[np.ndarray, int]:
        """(values, texture id or −1) for the compiled kernels (backend/kernels/params.py)."""
        raise NotImplementedError


class ConstantParam(Param):
    def __init__(self, value: Any, channels: int):
        self.channels = channels
        v = np.asarray(value, dtype=np.float64)
        self.value = v.reshape(1, 3) if channels == 3 else v.reshape(())

    def bind(self, uv: np.ndarray) -> np.ndarray:
        return self.value

    def mean(self) -> np.ndarray:
        return self.value.reshape(3) if self.channels == 3 else self.value

    def kernel_pack(self, packer, channels: int, factor) -> tuple[np.ndarray, int]:
        values = np.broadcast_to(self.value.reshape(-1) * factor, (channels,))
        return np.array(values, np.float64), -1


class ImageParam(Param):
    """Bilinear, repeating image lookup, times a constant ``scale``."""

    is_constant = False

    def __init__(self, texels: np.ndarray, channels: int, scale: np.ndarray, source: str):
        self.texels = texels  # (H, W, channels) float32, already sanitised and linear
        self.channels = channels
        self.scale = np.asarray(scale, dtype=np.float64)
        self.source = source

    def bind(self, uv: np.ndarray) -> np.ndarray:
        # The renderer's own lookup (backend/kernels/textures.py), over this one image.
        from .kernels.textures import build_table, lookup_batch
        if getattr(self, "_table", None) is None:
            self._table = build_table([self.texels])
        out = np.empty((uv.shape[0], self.channels))
        lookup_batch(self._table, 0, np.ascontiguousarray(uv, dtype=np.float64), out)
        if self.channels == 1:
            return out[:, 0] * self.scale
        return out * self.scale

    def mean(self) -> np.ndarray:
        m = self.texels.reshape(-1, self.channels).mean(axis=0).astype(np.float64) * self.scale
        return m if self.channels == 3 else m[0]

    def kernel_pack(self, packer, channels: int, factor) -> tuple[np.ndarray, int]:
        values = np.broadcast_to(self.scale * factor, (channels,))
        return np.array(values, np.float64), packer.texture_id(self.texels)


def image_param(ctx, file: str, path: str, channels: int, channel: int, colorspace: str, color: bool,
                lo, hi, scale) -> "ImageParam":
    """The image texture of a parameter field (``path``), read, decoded and sanitised."""
    texels = load_texels(ctx, file, f"{path}.texture", channels, channel, colorspace, color)
    texels = sanitise_texels(texels, ctx, path, lo, hi, scale)
    return ImageParam(texels, channels, scale, file)


#: What a texture that cannot be read renders as (Cycles' colour for a missing image).
MISSING_TEXTURE_RGB = (1.0, 0.0, 1.0)


def read_texture(ctx, resolved: Path, path: str) -> tuple[np.ndarray, bool]:
    """``read_image``, except that an image that cannot be read (missing, unreadable, corrupt)
    becomes one magenta texel and a warning naming the field and the file, unless the scene's
    ``render.missing_textures`` is "error" (or the CLI's --strict): a farm frame should fail, an
    artist's preview should show where the texture is missing, as in Cycles. Too large for the
    memory stays an error: magenta would hide a scene that cannot render as made."""
    try:
        return read_image(resolved, ctx.where, path)
    except SceneError as exc:
        if ctx.missing_textures == "error" or " is too large: " in exc.message:
            raise
        ctx.warn(path, f"{exc.message}: rendered magenta (an error with render.missing_textures "
                       f"\"error\" or the CLI's --strict)")
        return np.array(MISSING_TEXTURE_RGB, np.float32).reshape(1, 1, 3), True


def load_texels(ctx, file: str, path: str, channels: int, channel: int, colorspace: str,
                color: bool) -> np.ndarray:
    resolved = ctx.resolve(file, path)
    key = ("image", str(resolved))
    if key not in ctx.cache:
        ctx.cache[key] = read_texture(ctx, resolved, path)
    pixels, is_float = ctx.cache[key]
    decode_srgb = (colorspace == "sRGB") or (colorspace == "auto" and color and not is_float)
    c = pixels.shape[2]
    if channels == 3:
        if c >= 3:
            out = pixels[:, :, :3]
        else:
            out = np.repeat(pixels[:, :, :1], 3, axis=2)
        if decode_srgb:
            out = srgb_to_linear(out)
    else:
        pick = channel if channel >= 0 else 0
        if pick >= c:
            raise ctx.error(path, f"image has {c} channel(s), channel {pick} requested")
        if channel < 0 and c >= 3:
            # A colour image for a scalar parameter: use its luminance (Rec.709 weights). In
            # float64, rounded once to float32: a float32 product depends on the BLAS kernel the
            # CPU gets (an AMD machine's differed from an Intel one's by 4 ulps, which tilted a
            # grey ramp's bump normal), while this gives every machine the same texels, and a grey
            # texel exactly its own value.
            rgb = srgb_to_linear(pixels[:, :, :3]) if decode_srgb else pixels[:, :, :3]
            out = (rgb.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722]))[:, :, None]
        else:
            out = pixels[:, :, pick:pick + 1]
            if decode_srgb:
                out = srgb_to_linear(out)
    return np.ascontiguousarray(out, dtype=np.float32)


def sanitise_texels(texels: np.ndarray, ctx, path: str, lo, hi, scale) -> np.ndarray:
    bad = ~np.isfinite(texels)
    if bad.any():
        ctx.warn(path, f"{int(bad.sum())} NaN/Inf texel value(s) replaced by 0")
        texels = np.where(bad, 0.0, texels).astype(np.float32)
    # Range applies to the scaled value; scale is positive in sane use, so clamp texels. An open
    # upper bound is MAX_NUMBER, as for constants (backend/limits.py).
    if hi is None:
        from .limits import MAX_NUMBER
        hi = MAX_NUMBER
    # Per channel: a texel t gives t × scale_c, which must lie in [lo, hi] (scale_c >= 0 where
    # lo >= 0, parse_param; a zero scale makes every texel valid).
    s = np.broadcast_to(np.asarray(scale, dtype=np.float64).reshape(-1), (texels.shape[2],))
    out = texels.astype(np.float64)
    below = above = 0
    for c in range(texels.shape[2]):
        if s[c] <= 0:
            continue
        ch = out[:, :, c]
        if lo is not None:
            m = ch < lo / s[c]
            below += int(m.sum())
            ch[m] = lo / s[c]
        m = ch > hi / s[c]
        above += int(m.sum())
        ch[m] = hi / s[c]
    if below:
        ctx.warn(path, f"{below} texel value(s) below {lo:g} clamped")
    if above:
        ctx.warn(path, f"{above} texel value(s) above {hi:g} clamped")
    if below or above:
        texels = out.astype(np.float32)
    return texels
