"""Point lights per lane, as Cycles ≥ 4.0 (src/scene/light.cpp, src/kernel/light/point.h).

Units: the scene gives Blender's ``energy`` P [W]. With radius 0 the light is a delta light of
radiant intensity I = P/(4π) W/sr. With radius r > 0 the emitter has radiance
L = P/(4π² r²) W m⁻² sr⁻¹ (a sphere of that radiance emits exactly P), in one of Blender's two
shapes (``use_soft_falloff``):

* sphere (``soft_falloff`` false): a real sphere, sampled uniformly in the cone it subtends. A
  shading point inside the sphere sees radiance L from every direction; it is sampled uniformly
  over the sphere of directions (Cycles samples a cosine hemisphere around the normal there; our
  interface has no normal, any valid pdf gives the same expectation).
* soft falloff (Blender's default): a disk of radius r centred on the light and facing the
  shading point, sampled by area. Far away it equals the sphere; close by, its irradiance is
  I/(d² + r²) instead of I/d², hence the name.

A directional factor (spot cone, spot.py; IES profile, ies.py) multiplies the emission along the
direction the light travels, in the light's local frame ``normalize(M⁻¹ w)``. Inside a sphere
light Cycles applies no directional factor, and neither do we. Like Cycles, a sphere spot light
seen from close by samples the (wider) cone of the spot instead of the sphere's visible cone when
that is narrower: directions outside the spot cone carry no light anyway ("spread" cone).

IES: intensity I(ω) = P × candela(ω_local)/177.83 W/sr, i.e. the factor 4π·cd/177.83 on P/(4π)
(``P_IES_SCALE`` = 4π/177.83; backend/ies/light.py).

Precision: the sphere's visible cone is kept as 1 − cos α, from sin²α = r²/d² without
cancellation (common.sin2_to_one_minus_cos), never as cos α: a 1 cm sphere 100 m away has
1 − cos α ≈ 5e-9, of which cos α would keep one digit. float64 throughout.
"""
from __future__ import annotations

import math

from ..jit import kernel
from ..vec import coordinate_system, cross, dot
from ..consts import INV_4PI
from ..warp import cone_pdf, disk_concentric, uniform_sphere
from . import ies as _ies
from .common import (FIRST, I_FIRST, INF, ZERO3, get3, mat3, ray_sphere, sample_cone,
                     sin2_to_one_minus_cos, unit_or_zero)
from .spot import attenuation

# The kind code of this light in the light table (unique within the family: dispatch.py KINDS).
POINT = 0          # point / sphere / soft-falloff disk; optional spot cone and IES profile

# float columns
P_POS = FIRST            # 3: centre [m]
P_INTENSITY = FIRST + 3  # 3: colour × P/(4π) [W/sr] (radius 0)
P_RADIANCE = FIRST + 6   # 3: colour × P/(4π² r²) [W m⁻² sr⁻¹] (radius > 0)
P_RADIUS = FIRST + 9     # r [m]
P_TO_LOCAL = FIRST + 10  # 9: M⁻¹ row-major (world → light object frame, for the directional factor)
P_COS_HALF = FIRST + 19  # spot: cos(spot_size/2)
P_SPOT_SMOOTH = FIRST + 20   # spot: 1/((1 − cos_half)·blend), inf for a hard edge
P_SPREAD_AXIS = FIRST + 21   # 3: unit, towards the light from lit points (spot spread cone)
P_SPREAD_OMC = FIRST + 24    # 1 − cos of the spread cone's world half-angle; < 0: no spread cone
P_IES_SCALE = FIRST + 25     # 4π/177.83: candela → factor on P/(4π)

# int columns
I_SHAPE = I_FIRST        # SHAPE_*
I_SPOT = I_FIRST + 1     # 1: spot falloff applies
I_IES_OFF = I_FIRST + 2  # aux offset of the IES table block (ies.py)
I_IES_NH = I_FIRST + 3   # 0: no IES profile
I_IES_NV = I_FIRST + 4
I_IES_FLAGS = I_FIRST + 5

SHAPE_DELTA = 0
SHAPE_SPHERE = 1
SHAPE_DISK = 2


@kernel
def directional_factor(P, I, li, aux, w_out):
    """Factor on the emission travelling along world direction ``w_out`` (1 without spot/IES)."""
    spot = I[li, I_SPOT] != 0
    nh = I[li, I_IES_NH]
    if not spot and nh == 0:
        return 1.0
    loc, _ = unit_or_zero(mat3(P, li, P_TO_LOCAL, w_out))
    f = 1.0
    if spot:
        f = attenuation(-loc[2], P[li, P_COS_HALF], P[li, P_SPOT_SMOOTH])
    if nh > 0:
        f *= P[li, P_IES_SCALE] * _ies.intensity(aux, I[li, I_IES_OFF], nh, I[li, I_IES_NV], I[li, I_IES_FLAGS], loc)
    return f


@kernel
def _scaled(c, s):
    return (c[0] * s, c[1] * s, c[2] * s)


@kernel
def _cones(P, li, d2):
    """(outside the sphere?, 1 − cos of the sphere's cone, use the spread cone?)."""
    r = P[li, P_RADIUS]
    r2 = r * r
    outside = d2 > r2
    omc_sphere = sin2_to_one_minus_cos(r2 / d2 if d2 != 0.0 else 0.0)
    spread = P[li, P_SPREAD_OMC]
    use_spread = outside and spread >= 0.0 and spread < omc_sphere
    return outside, omc_sphere, use_spread


@kernel
def _sphere_distance(oc, wi, r2, outside, must_hit):
    """Distance along unit wi from o (oc = o − centre) to the sphere; inf on a miss.

    The discriminant uses the perpendicular distance |oc × wi| (no cancellation); directions
    drawn inside the sphere's cone always hit, so rounding at the silhouette is clamped there."""
    b = dot(oc, wi)
    perp = cross(oc, wi)
    disc = r2 - dot(perp, perp)
    if disc < 0.0 and not must_hit:
        return INF
    sq = math.sqrt(max(disc, 0.0))
    t = -b - sq if outside else -b + sq
    return t if t > 0.0 else INF


@kernel
def sample(P, I, li, aux, p, u0, u1):
    """(wi, dist, value, pdf); value = radiance/pdf, or I/d² for the delta light (pdf 0)."""
    pos = get3(P, li, P_POS)
    shape = I[li, I_SHAPE]
    if shape == SHAPE_DELTA:
        v = (pos[0] - p[0], pos[1] - p[1], pos[2] - p[2])
        d2 = dot(v, v)
        wi, dist = unit_or_zero(v)
        s = directional_factor(P, I, li, aux, (-wi[0], -wi[1], -wi[2])) * (1.0 / d2 if d2 != 0.0 else 0.0)
        return wi, dist, _scaled(get3(P, li, P_INTENSITY), s), 0.0
    oc = (p[0] - pos[0], p[1] - pos[1], p[2] - pos[2])
    d2 = dot(oc, oc)
    r = P[li, P_RADIUS]
    rad = get3(P, li, P_RADIANCE)
    if shape == SHAPE_SPHERE:
        outside, omc_sphere, use_spread = _cones(P, li, d2)
        if outside:
            if use_spread:
                axis = get3(P, li, P_SPREAD_AXIS)
                omc = P[li, P_SPREAD_OMC]
            else:
                axis, _ = unit_or_zero((-oc[0], -oc[1], -oc[2]))
                omc = omc_sphere
            wi = sample_cone(axis, omc, u0, u1)
            pdf = cone_pdf(omc)
        else:
            wi = uniform_sphere(u0, u1)
            pdf = INV_4PI
        t = _sphere_distance(oc, wi, r * r, outside, not use_spread)
        if not (t < INF) or not pdf > 0.0:
            return wi, 0.0, ZERO3, 0.0
        f = directional_factor(P, I, li, aux, (-wi[0], -wi[1], -wi[2])) if outside else 1.0
        return wi, t, _scaled(rad, f / pdf), pdf
    # soft-falloff disk facing the point, sampled by area
    light_n, _ = unit_or_zero(oc)
    s, tt = coordinate_system(light_n)
    dx, dy = disk_concentric(u0, u1)
    dx *= r
    dy *= r
    x = (pos[0] + dx * s[0] + dy * tt[0], pos[1] + dx * s[1] + dy * tt[1], pos[2] + dx * s[2] + dy * tt[2])
    wi, t = unit_or_zero((x[0] - p[0], x[1] - p[1], x[2] - p[2]))
    cos_l = -dot(light_n, wi)
    den = math.pi * r * r * cos_l
    pdf = t * t / den if den != 0.0 else 0.0
    if not (cos_l > 0.0 and t > 0.0 and d2 > 0.0 and pdf > 0.0):
        return wi, t, ZERO3, 0.0
    f = directional_factor(P, I, li, aux, (-wi[0], -wi[1], -wi[2]))
    return wi, t, _scaled(rad, f / pdf), pdf


@kernel
def intersect(P, I, li, o, d, tmax):
    shape = I[li, I_SHAPE]
    if shape == SHAPE_DELTA:
        return INF
    pos = get3(P, li, P_POS)
    r = P[li, P_RADIUS]
    if shape == SHAPE_SPHERE:
        return ray_sphere(o, d, pos, r, tmax)
    oc = (o[0] - pos[0], o[1] - pos[1], o[2] - pos[2])
    light_n, dist = unit_or_zero(oc)
    denom = dot(d, light_n)
    if not (denom < 0.0 and dist > 0.0):
        return INF
    t = dist / -denom
    x = (oc[0] + t * d[0], oc[1] + t * d[1], oc[2] + t * d[2])
    if t < tmax and dot(x, x) <= r * r:
        return t
    return INF


@kernel
def eval_hit(P, I, li, aux, o, d, t):
    """Radiance arriving at o from direction d (emitted at o + t d)."""
    shape = I[li, I_SHAPE]
    if shape == SHAPE_DELTA:
        return ZERO3
    rad = get3(P, li, P_RADIANCE)
    if shape == SHAPE_SPHERE:
        pos = get3(P, li, P_POS)
        oc = (o[0] - pos[0], o[1] - pos[1], o[2] - pos[2])
        r = P[li, P_RADIUS]
        if not dot(oc, oc) > r * r:
            return rad        # inside the sphere: no directional factor (as Cycles)
    return _scaled(rad, directional_factor(P, I, li, aux, (-d[0], -d[1], -d[2])))


@kernel
def pdf_hit(P, I, li, o, d, t):
    """Solid-angle density with which ``sample(o)`` produces direction d."""
    shape = I[li, I_SHAPE]
    if shape == SHAPE_DELTA:
        return 0.0
    pos = get3(P, li, P_POS)
    oc = (o[0] - pos[0], o[1] - pos[1], o[2] - pos[2])
    d2 = dot(oc, oc)
    if shape == SHAPE_SPHERE:
        outside, omc_sphere, use_spread = _cones(P, li, d2)
        if use_spread:
            axis = get3(P, li, P_SPREAD_AXIS)
            omc = P[li, P_SPREAD_OMC]
            return cone_pdf(omc) if (1.0 - dot(d, axis)) <= omc else 0.0
        return cone_pdf(omc_sphere) if outside else INV_4PI
    light_n, _ = unit_or_zero(oc)
    cos_l = -dot(light_n, d)
    r = P[li, P_RADIUS]
    den = math.pi * r * r * cos_l
    if cos_l > 0.0 and den != 0.0:
        return t * t / den
    return 0.0
