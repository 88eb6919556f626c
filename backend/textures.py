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
    """Read an image as float32 (H, W, C). Returns (pixels, is_float_format). Raises SceneError."""
    try:
        import OpenImageIO as oiio
    except ImportError as exc:  # pragma: no cover - dependency is pinned
        raise SceneError(where, field, f"OpenImageIO is not installed ({exc})") from exc
    if not Path(path).is_file():
        raise SceneError(where, field, f"texture file not found: {path}")
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise SceneError(where, field, f"cannot read image {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if pixels is None:
            raise SceneError(where, field, f"cannot decode image {path}: {inp.geterror()}")
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


def load_texels(ctx, file: str, path: str, channels: int, channel: int, colorspace: str,
                color: bool) -> np.ndarray:
    resolved = ctx.resolve(file)
    key = ("image", str(resolved))
    if key not in ctx.cache:
        ctx.cache[key] = read_image(resolved, ctx.where, path)
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
            # A colour image for a scalar parameter: use its luminance (Rec.709 weights).
            rgb = srgb_to_linear(pixels[:, :, :3]) if decode_srgb else pixels[:, :, :3]
            out = (rgb @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32))[:, :, None]
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
    # Range applies to the scaled value; scale is positive in sane use, so clamp texels.
    s = np.asarray(scale, dtype=np.float64)
    s_min = float(np.min(s)) if s.size else 1.0
    if s_min > 0:
        lo_t = None if lo is None else lo / s_min
        hi_t = None if hi is None else hi / float(np.max(s))
        out = texels
        if lo_t is not None and (out < lo_t).any():
            ctx.warn(path, f"{int((out < lo_t).sum())} texel value(s) below {lo:g} clamped")
            out = np.maximum(out, lo_t)
        if hi_t is not None and (out > hi_t).any():
            ctx.warn(path, f"{int((out > hi_t).sum())} texel value(s) above {hi:g} clamped")
            out = np.minimum(out, hi_t)
        texels = out.astype(np.float32)
    return texels
