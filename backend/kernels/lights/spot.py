"""Spot-light cone falloff per lane, as Cycles ≥ 4.0 (src/scene/light.cpp, src/kernel/light/spot.h).

The falloff is evaluated on the direction the light travels expressed in the light object's local
frame (``M⁻¹ w``, normalised; the cone axis is local −Z)::

    z'    = −(M⁻¹ w / |M⁻¹ w|)_z                 cosine to the cone axis in local space
    x     = (z' − cos(spot_size/2)) / ((1 − cos(spot_size/2)) · spot_blend)
    atten = smoothstep(x) = 0 (x ≤ 0), 1 (x ≥ 1), x²(3 − 2x) otherwise

so a non-uniformly scaled spot light has an elliptical cone, as in Blender. ``spot_blend`` = 0
gives a hard edge (``spot_smooth`` = ∞). The point light kernel (point.py) applies it, times an
optional IES profile, to its emission.
"""
from __future__ import annotations

import math

from ..jit import kernel


@kernel
def attenuation(cos_axis, cos_half_angle, spot_smooth):
    """Cycles' spot falloff of the local cosine to the cone axis.

    ``spot_smooth`` = 1/((1 − cos_half_angle) · spot_blend); ∞ for a hard edge."""
    if not math.isfinite(spot_smooth):
        return 1.0 if cos_axis > cos_half_angle else 0.0
    x = min(max((cos_axis - cos_half_angle) * spot_smooth, 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)
