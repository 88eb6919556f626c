"""World lights per lane: a constant colour and an equirectangular environment map.

Orientation is Blender's Environment Texture (Cycles ``direction_to_equirectangular``): for a unit
direction (x, y, z) in the map's frame,

    u = 0.5 − atan2(y, x) / 2π        (image column, 0 = left edge)
    v = 1 − acos(z) / π               (0 = bottom row, 1 = top row)

so the image centre looks along +X, a quarter from the left along +Y, the top row is +Z (up).
Here ``x`` = u and ``y`` = acos(z)/π = 1 − v (image rows from the top). Lookups are bilinear
between texel centres (Blender's default "Linear" interpolation), wrapping around in u and
clamped at the poles. ``E_TO_WORLD`` maps the map's frame to the world (the rotation part of the
scene's ``to_world``: a Blender Mapping node with rotation R in front of the texture is Rᵀ).

Importance sampling: a piecewise-constant density over the texels (discrete.py, 2-D block)
proportional to the luminance of the texel and its 8 neighbours (their maximum, so every direction
where the bilinear radiance is non-zero has a non-zero pdf) times the texel row's solid angle; the
solid-angle pdf is p(u, v) / (2π² sin θ). Radiance in W m⁻² sr⁻¹ (texel × strength), float64
texels in ``aux`` (row 0 = the top of the image, RGB).

The constant world: radiance L from every direction, sampled uniformly (pdf 1/4π).
"""
from __future__ import annotations

import math

from .. import discrete as _d
from ..jit import kernel
from ..turns import cos_sin_turns
from ..consts import INV_4PI
from ..warp import uniform_sphere
from .common import FIRST, I_FIRST, INF, get3, mat3, unit_or_zero

# Kind codes (unique within the family: dispatch.py KINDS).
CONSTANT = 4       # uniform world
ENVIRONMENT = 5    # equirectangular environment map

W_RADIANCE = FIRST       # constant world: 3, [W m⁻² sr⁻¹]

E_TO_WORLD = FIRST       # 9: row-major rotation, map frame → world
E_TO_LOCAL = FIRST + 9   # 9: its transpose
I_TEX_OFF = I_FIRST      # aux offset of the texels (h × w × 3)
I_H = I_FIRST + 1
I_W = I_FIRST + 2
I_DIST_OFF = I_FIRST + 3     # aux offset of the 2-D distribution block (h × w)

TWO_PI_SQ = 2.0 * math.pi * math.pi


# ---------------------------------------------------------------- constant world
@kernel
def constant_sample(P, li, u0, u1):
    wi = uniform_sphere(u0, u1)
    inv = 1.0 / INV_4PI
    return wi, INF, (P[li, W_RADIANCE] * inv, P[li, W_RADIANCE + 1] * inv, P[li, W_RADIANCE + 2] * inv), INV_4PI


@kernel
def constant_eval(P, li):
    return get3(P, li, W_RADIANCE)


# ---------------------------------------------------------------- environment map
@kernel
def lookup(aux, I, li, x, y):
    """Bilinear radiance at image coordinates x (column, wraps) and y (row from top, clamps)."""
    h = I[li, I_H]
    w = I[li, I_W]
    off = I[li, I_TEX_OFF]
    fx = x * w - 0.5
    fy = min(max(y * h - 0.5, 0.0), h - 1.0)
    if not (math.isfinite(fx) and math.isfinite(fy)):
        return (0.0, 0.0, 0.0)
    x0f = math.floor(fx)
    y0f = math.floor(fy)
    ax = fx - x0f
    ay = fy - y0f
    x0 = int(x0f) % w
    x1 = (x0 + 1) % w
    y0 = int(y0f)
    y1 = min(y0 + 1, h - 1)
    a = off + (y0 * w + x0) * 3
    b = off + (y0 * w + x1) * 3
    c = off + (y1 * w + x0) * 3
    d = off + (y1 * w + x1) * 3
    gx = 1.0 - ax
    gy = 1.0 - ay
    return ((aux[a] * gx + aux[b] * ax) * gy + (aux[c] * gx + aux[d] * ax) * ay,
            (aux[a + 1] * gx + aux[b + 1] * ax) * gy + (aux[c + 1] * gx + aux[d + 1] * ax) * ay,
            (aux[a + 2] * gx + aux[b + 2] * ax) * gy + (aux[c + 2] * gx + aux[d + 2] * ax) * ay)


@kernel
def direction_to_xy(P, li, d):
    """World direction → (x, y) in [0, 1]², x = u, y = θ/π, and the unit map-frame direction."""
    loc, _ = unit_or_zero(mat3(P, li, E_TO_LOCAL, d))
    u = 0.5 - math.atan2(loc[1], loc[0]) / (2.0 * math.pi)
    u = u - math.floor(u)
    y = math.acos(min(max(loc[2], -1.0), 1.0)) / math.pi
    return u, y, loc


@kernel
def xy_to_direction(P, li, x, y):
    """(world direction, sin θ) of image coordinates (x, y)."""
    ct, s = cos_sin_turns(0.5 * y)             # θ = π·y
    cp, sp = cos_sin_turns(0.5 - x)            # φ = π − 2π·x, the inverse of u = 0.5 − φ/2π
    loc = (s * cp, s * sp, ct)
    wi, _ = unit_or_zero(mat3(P, li, E_TO_WORLD, loc))
    return wi, s


@kernel
def env_sample(P, I, li, aux, u0, u1):
    x, y, pdf_xy = _d.sample_2d(aux, I[li, I_DIST_OFF], I[li, I_H], I[li, I_W], u0, u1)
    wi, sin_t = xy_to_direction(P, li, x, y)
    den = TWO_PI_SQ * sin_t
    pdf = pdf_xy / den if den != 0.0 else 0.0
    if not pdf > 0.0:
        return wi, INF, (0.0, 0.0, 0.0), pdf
    le = lookup(aux, I, li, x, y)
    inv = 1.0 / pdf
    return wi, INF, (le[0] * inv, le[1] * inv, le[2] * inv), pdf


@kernel
def env_eval(P, I, li, aux, d):
    x, y, _ = direction_to_xy(P, li, d)
    return lookup(aux, I, li, x, y)


@kernel
def env_pdf(P, I, li, aux, d):
    x, y, loc = direction_to_xy(P, li, d)
    sin_t = math.hypot(loc[0], loc[1])      # precise near the poles, unlike √(1 − z²)
    pdf_xy = _d.pdf_2d(aux, I[li, I_DIST_OFF], I[li, I_H], I[li, I_W], x, y)
    den = TWO_PI_SQ * sin_t
    return pdf_xy / den if den != 0.0 else 0.0
