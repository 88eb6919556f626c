"""Warps from uniform numbers in [0, 1)² to points and directions, per lane, with densities.

Densities are per unit solid angle (directions) or area (points). ``backend/sampling/warp.py``
exposes the same warps on arrays (for tests and NumPy callers) by looping over these.
"""
from __future__ import annotations

import math

from .jit import kernel
from .turns import cos_sin_turns

from .consts import PI


@kernel
def disk_concentric(u0, u1):
    """Shirley–Chiu concentric map of the square onto the unit disk."""
    a = 2.0 * u0 - 1.0
    b = 2.0 * u1 - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if abs(a) > abs(b):
        r = a
        turns = 0.125 * (b / a)             # φ = (π/4)(b/a)
    else:
        r = b
        turns = 0.25 - 0.125 * (a / b)      # φ = π/2 − (π/4)(a/b)
    c, s = cos_sin_turns(turns)
    return r * c, r * s


@kernel
def cosine_hemisphere(u0, u1):
    """Malley's method with the polar disk map (r = √u0, φ = 2π u1); pdf cos θ / π."""
    r = math.sqrt(u0)
    c, s = cos_sin_turns(u1)
    return (r * c, r * s, math.sqrt(max(0.0, 1.0 - u0)))


@kernel
def uniform_sphere(u0, u1):
    z = 1.0 - 2.0 * u0
    r = math.sqrt(max(0.0, 1.0 - z * z))
    c, s = cos_sin_turns(u1)
    return (r * c, r * s, z)


@kernel
def uniform_cone_local(u0, u1, one_minus_cos):
    """Uniform direction within the cone around +z of 1 − cos α = ``one_minus_cos`` (from 1 − cos,
    not cos, so tiny cones such as a 0.5° sun keep their precision); pdf 1/(2π(1 − cos α))."""
    omz = u0 * one_minus_cos
    z = 1.0 - omz
    sin_t = math.sqrt(max(omz * (2.0 - omz), 0.0))
    c, s = cos_sin_turns(u1)
    return (sin_t * c, sin_t * s, z)


@kernel
def cone_pdf(one_minus_cos):
    return 1.0 / (2.0 * PI * one_minus_cos) if one_minus_cos > 0.0 else 0.0


@kernel
def triangle_barycentric(u0, u1):
    """Uniform barycentrics (b0, b1), b0 + b1 ≤ 1 (Heitz 2019's low-distortion map)."""
    if u0 <= u1:
        b0 = 0.5 * u0
        b1 = u1 - b0
    else:
        b1 = 0.5 * u1
        b0 = u0 - b1
    return b0, b1
