"""Kind codes, the column layout shared by every light, and small geometry helpers.

A light is one row of the light table (table.py): ``params[li]`` (float64, ``NP`` columns) and
``iparams[li]`` (int64, ``NI`` columns). Kernels take the whole matrices ``P``, ``I`` and the row
``li``, never a row view: a view made per lane and passed to a function that is not inlined costs
two atomic reference-count updates each (measured: 40 → 120 ns per point-light sample). Columns 0–11 / 0 are common to all kinds (light
selection reads them without knowing the kind); each kind module defines its own columns from
``FIRST`` / ``I_FIRST`` on.

Conventions (docs/architecture.md, Frames, units, precision): world space is Blender's (right-handed, Z up, metres); a light
object shines down its local −Z; directions are unit 3-tuples, float64.
"""
from __future__ import annotations

import math

from ..jit import kernel
from ..vec import coordinate_system, dot, length
from ..warp import uniform_cone_local

# ------------------------------------------------------------------ table rows
# (each kind's code is in its own module: dispatch.py KINDS lists them)
NP = 48            # float64 columns per light
NI = 12            # int64 columns per light

# ------------------------------------------------------------------ common columns
C_POWER = 0        # selection power (W × luminance, or the light's own estimate); 0 = never picked
C_SEL_POS = 1      # 1..3: where the light is, for the received-power estimate [m]
C_SEL_SIZE2 = 4    # squared size [m²] below which the distance stops mattering (≥ 1e-8)
C_SEL_NORMAL = 5   # 5..7: one-sided emitters' normal
C_SEL_AREA = 8     # one-sided emitters' area [m²]
C_SEL_INTENSITY = 9  # SEL_PROFILE: luminance of the unit-factor intensity, lum · P/(4π) [W/sr]
C_SEL_PEAK = 10    # SEL_ONE_SIDED_PROFILE: 1/K, the profile's peak radiance over a Lambertian emitter's
FIRST = 12

I_SEL = 0          # how selection weighs the light at a point: SEL_*
I_FIRST = 1

SEL_UNIFORM = 0    # the same everywhere: power / (π R²) (infinite lights)
SEL_POINT = 1      # power / (4π max(d², size²))
SEL_ONE_SIDED = 2  # power · max(cos, 0.05) / (π max(d², area)) in front, 0 behind
SEL_ONE_SIDED_PROFILE = 4  # area light with spread/cutoff: SEL_ONE_SIDED × its profile towards p
SEL_PROFILE = 3    # point/spot/IES with a directional factor: I(ω) / max(d², size²), ω towards p,
                   # so no sample goes where the spot cone or the IES table is zero

ZERO3 = (0.0, 0.0, 0.0)
INF = math.inf


@kernel
def get3(P, li, c):
    """Columns c..c+2 of light li's row of the parameter matrix P."""
    return (P[li, c], P[li, c + 1], P[li, c + 2])


@kernel
def mat3(P, li, c, v):
    """The row-major 3×3 matrix stored at columns c..c+8 of light li's row, applied to v."""
    return (P[li, c] * v[0] + P[li, c + 1] * v[1] + P[li, c + 2] * v[2],
            P[li, c + 3] * v[0] + P[li, c + 4] * v[1] + P[li, c + 5] * v[2],
            P[li, c + 6] * v[0] + P[li, c + 7] * v[1] + P[li, c + 8] * v[2])


@kernel
def aux3(a, i):
    """a[i:i+3] of a 1-D array as a tuple."""
    return (a[i], a[i + 1], a[i + 2])


@kernel
def sin2_to_one_minus_cos(s2):
    """1 − cos α from sin²α without cancellation for small angles (α ≤ 90°)."""
    s2 = min(max(s2, 0.0), 1.0)
    return s2 / (1.0 + math.sqrt(1.0 - s2))


@kernel
def sample_cone(axis, one_minus_cos, u0, u1):
    """Uniform direction within the cone of 1 − cos α = ``one_minus_cos`` around unit ``axis``;
    pdf 1/(2π(1 − cos α)) (warp.cone_pdf)."""
    loc = uniform_cone_local(u0, u1, one_minus_cos)
    s, t = coordinate_system(axis)
    return (loc[0] * s[0] + loc[1] * t[0] + loc[2] * axis[0],
            loc[0] * s[1] + loc[1] * t[1] + loc[2] * axis[1],
            loc[0] * s[2] + loc[1] * t[2] + loc[2] * axis[2])


@kernel
def ray_sphere(o, d, center, radius, tmax):
    """First t in (0, tmax) where o + t d meets the sphere (from outside or inside); inf if none."""
    oc = (o[0] - center[0], o[1] - center[1], o[2] - center[2])
    b = dot(oc, d)
    c = dot(oc, oc) - radius * radius
    disc = b * b - c
    if not disc >= 0.0:
        return INF
    sq = math.sqrt(disc)
    # Numerically stable roots: q = −b − sign(b)√disc, t0 = q, t1 = c/q.
    q = -b - math.copysign(sq, b)
    t_b = c / q if q != 0.0 else 0.0
    t_near = min(q, t_b)
    t_far = max(q, t_b)
    t = t_near if t_near > 0.0 else t_far
    if t > 0.0 and t < tmax:
        return t
    return INF


@kernel
def unit_or_zero(v):
    """(v/|v|, |v|); the zero vector stays zero."""
    n = length(v)
    if n > 0.0:
        inv = 1.0 / n
        return (v[0] * inv, v[1] * inv, v[2] * inv), n
    return v, 0.0
