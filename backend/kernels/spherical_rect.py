"""Uniform sampling of the solid angle subtended by a rectangle, per lane (Ureña, Fajardo, King
2013, "An Area-Preserving Parametrization for Spherical Rectangles").

Everything is expressed in the rectangle's frame (unit edge directions ex, ey and ez = ex × ey)
with the reference point at the origin: a lane gives the coordinates (x0, y0, z0) of the
rectangle's corner relative to its reference point and the edge lengths; samples come back as
in-plane coordinates (xu, yv), so the sampled point is o + xu·ex + yv·ey + z0·ez.

The solid angle is computed from the four internal angles through arcsin (as Cycles does), so
small rectangles do not lose it to cancellation against 2π. float64: the solid angle of a light
far away is a small difference of angles; below ~1e-8 sr callers switch to area sampling.

A spherical rectangle is the tuple ``(x0, x1, y0, y1, z0, b0, b1, g23, solid_angle)``:
[x0, x1] × [y0, y1] in the plane at signed distance z0 ≤ 0 (the frame's z axis mirrored where
needed so that the plane lies on its negative side), the z components b0, b1 of two edge-plane
normals, and g23 = g2 + g3 of the internal-angle terms.
"""
from __future__ import annotations

import math

from .jit import kernel


@kernel
def _asin(x):
    return math.asin(min(max(x, -1.0), 1.0))


@kernel
def spherical_rect(x0, y0, z0, lx, ly):
    """The spherical rectangle of corner (x0, y0, z0) + [0, lx]·ex + [0, ly]·ey seen from the origin.

    Mirroring z (z0 → −|z0|) does not change which points are sampled: xu, yv and |z0| describe
    the same point, and the caller rebuilds it with its own, unmirrored z0."""
    z0 = -abs(z0)
    x1 = x0 + lx
    y1 = y0 + ly
    z2 = z0 * z0
    # z components of the four edge-plane normals, n_i = (…, …, c_i)/l_i.
    nz0 = -y0 / math.sqrt(z2 + y0 * y0)
    nz1 = x1 / math.sqrt(z2 + x1 * x1)
    nz2 = y1 / math.sqrt(z2 + y1 * y1)
    nz3 = -x0 / math.sqrt(z2 + x0 * x0)
    # γ_i = π/2 − g_i with g_i = asin(−n_i·n_{i+1}); S = Σγ_i − 2π = −Σg_i.
    g2 = _asin(-nz2 * nz3)
    g3 = _asin(-nz3 * nz0)
    g23 = g2 + g3
    solid = -(_asin(-nz0 * nz1) + _asin(-nz1 * nz2) + g23)
    return (x0, x1, y0, y1, z0, nz0, nz2, g23, max(solid, 0.0))


@kernel
def sample(sr, u0, u1):
    """In-plane coordinates (xu, yv) of a point uniformly distributed in solid angle (density
    1/solid_angle) on the rectangle ``sr``."""
    x0, x1, y0, y1, z0, b0, b1, g23, solid = sr
    # Angle a_u = u·S + π + g2 + g3; the π flips the signs of both cos and sin and cancels in f_u.
    au = u0 * solid + g23
    ca = math.cos(au)
    sa = math.sin(au)
    if not abs(sa) > 1e-300:
        sa = 1e-300
    fu = (ca * b0 + b1) / sa
    cu = math.copysign(1.0, fu) / math.sqrt(fu * fu + b0 * b0)
    cu = min(max(cu, -1.0), 1.0)
    xu = -(cu * z0) / max(math.sqrt(max(1.0 - cu * cu, 0.0)), 1e-300)
    xu = min(max(xu, x0), x1)
    dd2 = xu * xu + z0 * z0
    dd = math.sqrt(dd2)
    h0 = y0 / math.sqrt(dd2 + y0 * y0)
    h1 = y1 / math.sqrt(dd2 + y1 * y1)
    hv = h0 + u1 * (h1 - h0)
    hv2 = hv * hv
    if hv2 < 1.0 - 1e-12:
        yv = hv * dd / math.sqrt(max(1.0 - hv2, 1e-300))
    else:
        yv = y1
    return xu, min(max(yv, y0), y1)
