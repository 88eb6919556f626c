"""World lights: a constant colour and an equirectangular environment map.

Orientation is Blender's Environment Texture (Cycles ``direction_to_equirectangular``): for a unit
direction (x, y, z) in the map's frame,

    u = 0.5 − atan2(y, x) / 2π        (image column, 0 = left edge)
    v = 1 − acos(z) / π               (0 = bottom row, 1 = top row)

so the image centre looks along +X, a quarter from the left along +Y, the top row is +Z (up).
Lookups are bilinear between texel centres (Blender's default "Linear" interpolation), wrapping
around in u and clamped at the poles. ``to_world`` maps the map's frame to the world (only its
rotation part is used); a Blender Mapping node (type Point or Vector) with rotation R in front of
the texture is ``to_world = Rᵀ``.

Importance sampling: a piecewise-constant density over the texels (``PiecewiseConstant2D``)
proportional to the luminance of the texel and its 8 neighbours (their maximum, so every direction
where the bilinear radiance is non-zero has a non-zero pdf) times the texel row's solid angle; the
solid-angle pdf is p(u, v) / (2π² sin θ).

Lookups, sampling and densities are per-lane code (``backend/kernels/lights/environment.py``);
these classes parse the world, build the texels and the distribution (load time) and pack them.
"""
from __future__ import annotations

import numpy as np

from ..kernels.lights import environment as _ke
from ..mathutil import LUMINANCE
from ..sampling.discrete import PiecewiseConstant2D
from ..textures import read_texture, srgb_to_linear
from . import register_world
from .base import Light
from .common import power_luminance


class ConstantWorld(Light):
    """Uniform radiance colour × strength from every direction, sampled uniformly."""

    is_infinite = True
    fills_sphere = True
    visible_camera = True
    # BSDF sampling is the better strategy for it everywhere (exact for a Lambertian surface:
    # zero variance, as in Cycles); its escaped rays then keep MIS weight 1.
    light_sampled = False

    def __init__(self, radiance):
        self.radiance = np.asarray(radiance, dtype=np.float64).reshape(3)
        self.scene_radius = 1.0

    def prepare(self, scene_center, scene_radius):
        self.scene_radius = float(scene_radius)

    def power(self) -> float:
        # Flux entering the scene's bounding sphere: π R² ∫ L dω = 4π² R² L.
        return power_luminance(self.radiance, 4.0 * np.pi ** 2 * self.scene_radius ** 2)

    def pack(self, b) -> None:
        row = b.light(_ke.CONSTANT, infinite=True, visible_camera=True)
        row.select_uniform()
        row.put(_ke.W_RADIANCE, self.radiance)


class EnvironmentMap(Light):
    is_infinite = True
    fills_sphere = True
    visible_camera = True

    def __init__(self, texels: np.ndarray, strength: float = 1.0, to_world: np.ndarray | None = None):
        """``texels``: (H, W, 3) linear RGB, row 0 = top of the image, finite and ≥ 0."""
        t = np.ascontiguousarray(texels, dtype=np.float64) * float(strength)
        self.texels = t
        self.h, self.w = t.shape[:2]
        m = np.eye(3) if to_world is None else np.asarray(to_world, dtype=np.float64)[:3, :3]
        # Only the rotation part counts (a scaled map would not keep solid angles): the nearest
        # orthogonal matrix, U Vᵀ of the SVD.
        su, _, svt = np.linalg.svd(m)
        self.to_world = su @ svt
        self.to_local = self.to_world.T
        # Row r covers θ in [r, r+1]·π/H; its solid angle per texel is Δφ (cos θ0 − cos θ1).
        edges = np.linspace(0.0, np.pi, self.h + 1)
        row_solid = (np.cos(edges[:-1]) - np.cos(edges[1:])) * (2.0 * np.pi / self.w)
        lum = t @ LUMINANCE
        self.integral = float(np.sum(lum * row_solid[:, None]))     # ∫ luminance dω
        self.dist = PiecewiseConstant2D(_dilate_max(lum) * row_solid[:, None])
        self.scene_radius = 1.0

    def prepare(self, scene_center, scene_radius):
        self.scene_radius = float(scene_radius)

    def power(self) -> float:
        return max(np.pi * self.scene_radius ** 2 * self.integral, 0.0)

    def pack(self, b) -> None:
        row = b.light(_ke.ENVIRONMENT, infinite=True, visible_camera=True)
        row.select_uniform()
        row.put(_ke.E_TO_WORLD, self.to_world)
        row.put(_ke.E_TO_LOCAL, self.to_local)
        row.i[_ke.I_TEX_OFF] = b.aux(self.texels)
        row.i[_ke.I_H] = self.h
        row.i[_ke.I_W] = self.w
        row.i[_ke.I_DIST_OFF] = b.aux(self.dist.block)


def _dilate_max(a: np.ndarray) -> np.ndarray:
    """Max over each texel's 3×3 neighbourhood (wrapping in x, clamped in y)."""
    out = a.copy()
    for dx in (-1, 0, 1):
        shifted = np.roll(a, dx, axis=1)
        out = np.maximum(out, shifted)
        out[1:] = np.maximum(out[1:], shifted[:-1])
        out[:-1] = np.maximum(out[:-1], shifted[1:])
    return out


# --------------------------------------------------------------------------- scene parsers

@register_world("constant")
def parse_constant(node) -> ConstantWorld:
    color = node.rgb("color", [0.05, 0.05, 0.05])
    strength = node.number("strength", 1.0, lo=0.0)
    return ConstantWorld(color * strength)


@register_world("environment")
def parse_environment(node) -> EnvironmentMap:
    file = node.string("file")
    strength = node.number("strength", 1.0, lo=0.0)
    colorspace = node.string("colorspace", "auto", choices=("auto", "sRGB", "linear"))
    to_world = node.matrix4("to_world", None) if node.has("to_world") else None
    if to_world is None:
        node.ignore("to_world")
    ctx = node.ctx
    field = node.sub("file")
    pixels, is_float = read_texture(ctx, ctx.resolve(file, field), field)   # missing: magenta
    rgb = pixels[:, :, :3] if pixels.shape[2] >= 3 else np.repeat(pixels[:, :, :1], 3, axis=2)
    if colorspace == "sRGB" or (colorspace == "auto" and not is_float):
        rgb = srgb_to_linear(rgb)
    rgb = sanitise_radiance(rgb, ctx, field)
    return EnvironmentMap(rgb, strength, to_world)


def sanitise_radiance(rgb: np.ndarray, ctx, field: str) -> np.ndarray:
    """NaN/Inf/negative texels become 0, with one warning each (never NaN in the renderer)."""
    rgb = np.asarray(rgb, dtype=np.float64)
    bad = ~np.isfinite(rgb)
    if bad.any():
        ctx.warn(field, f"{int(bad.sum())} NaN/Inf texel value(s) replaced by 0")
        rgb = np.where(bad, 0.0, rgb)
    neg = rgb < 0
    if neg.any():
        ctx.warn(field, f"{int(neg.sum())} negative texel value(s) replaced by 0")
        rgb = np.where(neg, 0.0, rgb)
    return rgb
