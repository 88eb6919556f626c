"""Emissive triangles (objects whose material has ``emission``) per lane, for next-event estimation.

One mesh light holds all emissive triangles of a scene (world space, float64). Sampling: a
triangle with probability ∝ area × luminance(radiance) (a 1-D distribution, discrete.py; a
textured emission weighs the triangle by its value at the UV centroid), then a uniform point on it
(Heitz's low-distortion square-to-triangle map); solid-angle pdf = P(tri)/area × t²/|cos θ_l|.
The value is the *exact* emitted radiance at the sampled point: for textured emission the
triangle's material emission parameter (``ParamPacker``: constant, or texture × scale) evaluated
at the UV interpolated with the sample's barycentrics, so next-event estimation stays unbiased.

Emission is two-sided by default: Cycles' emission shader emits from both faces (measured with
Cycles 5.0.1). A material with ``"emission_sides": "front"`` emits from the counter-clockwise
front only; the flag is per triangle (``T_TWO_SIDED``), so one mesh light holds both kinds.

The integrator intersects the triangles through embree (they are ordinary scene geometry): this
light is neither hittable nor infinite; ``pdf_hit_triangle`` gives the MIS density of a hit on
emitter triangle ``tri`` (its index among the emitters: the table maps scene primitives to it).

Layout: per triangle, ``TRI_STRIDE`` floats at ``I_TRI_OFF``: v0 (3), e1 = v1 − v0 (3),
e2 = v2 − v0 (3), unit normal e1 × e2 (3), area [m²], radiance (3) [W m⁻² sr⁻¹] (the per-triangle
value used to pick triangles, and the emission when nothing is textured), two-sided flag (1 both
faces, 0 the front only). Textured lights add the
UV corners (6 per triangle at ``I_UV_OFF``), the emission slot of each triangle (``iaux`` at
``I_SLOT_OFF``) and per slot its packed parameter: 3 values in ``aux`` at ``I_EMIT_OFF`` and a
texture id (−1: constant) in ``iaux`` at ``I_EMIT_TEX_OFF``.
"""
from __future__ import annotations

from .. import discrete as _d
from ..jit import inlined, kernel
from ..params import param_rgb
from ..vec import dot
from ..warp import triangle_barycentric
from .common import I_FIRST, ZERO3, aux3, unit_or_zero

MESH = 6           # kind code (unique within the family: dispatch.py KINDS): emissive triangles

TRI_STRIDE = 17
T_V0, T_E1, T_E2, T_N, T_AREA, T_RAD, T_TWO_SIDED = 0, 3, 6, 9, 12, 13, 16

I_TRI_OFF = I_FIRST
I_COUNT = I_FIRST + 1
I_DIST_OFF = I_FIRST + 2     # 1-D block over the triangles; −1: nothing emits
I_RESERVED = I_FIRST + 3     # (was the light-wide two-sided flag; now per triangle)
I_TEXTURED = I_FIRST + 4
I_UV_OFF = I_FIRST + 5
I_SLOT_OFF = I_FIRST + 6
I_EMIT_OFF = I_FIRST + 7
I_EMIT_TEX_OFF = I_FIRST + 8


@kernel
def _cos_light(I, li, aux, r, d):
    """Cosine between the emitter's front and the direction back from it (|·| if two-sided)."""
    c = -dot(d, aux3(aux, r + T_N))
    return abs(c) if aux[r + T_TWO_SIDED] != 0.0 else c


@kernel
def emitted(I, li, aux, iaux, tx, tri, b0, b1, b2):
    """Radiance of triangle ``tri`` at barycentrics (b0, b1, b2) of (v0, v1, v2)."""
    if I[li, I_TEXTURED] == 0:
        return aux3(aux, I[li, I_TRI_OFF] + tri * TRI_STRIDE + T_RAD)
    q = I[li, I_UV_OFF] + tri * 6
    u = b0 * aux[q] + b1 * aux[q + 2] + b2 * aux[q + 4]
    v = b0 * aux[q + 1] + b1 * aux[q + 3] + b2 * aux[q + 5]
    slot = iaux[I[li, I_SLOT_OFF] + tri]
    e = I[li, I_EMIT_OFF] + 3 * slot
    return param_rgb(tx, aux[e:e + 3], iaux[I[li, I_EMIT_TEX_OFF] + slot], u, v)


@kernel
def point_at(aux, r, b1, b2):
    """The point b0·v0 + b1·v1 + b2·v2 of the triangle at row ``r``, from v0 and the edges."""
    return (aux[r] + b1 * aux[r + T_E1] + b2 * aux[r + T_E2],
            aux[r + 1] + b1 * aux[r + T_E1 + 1] + b2 * aux[r + T_E2 + 1],
            aux[r + 2] + b1 * aux[r + T_E1 + 2] + b2 * aux[r + T_E2 + 2])


@inlined
def sample(I, li, aux, iaux, tx, p, u0, u1):
    wi, t, value, pdf, _ = sample_tri(I, li, aux, iaux, tx, p, u0, u1)
    return wi, t, value, pdf


@kernel
def sample_tri(I, li, aux, iaux, tx, p, u0, u1):
    """``sample`` and the emitter triangle it chose (−1: none), whose object's ray visibility
    and light linking the integrator then applies (scene/links.py)."""
    if I[li, I_DIST_OFF] < 0:
        return ZERO3, 0.0, ZERO3, 0.0, -1
    tri, prob, u_rem = _d.sample_1d(aux, I[li, I_DIST_OFF], I[li, I_COUNT], u0)
    b0, b1 = triangle_barycentric(u_rem, u1)
    b2 = 1.0 - b0 - b1
    r = I[li, I_TRI_OFF] + tri * TRI_STRIDE
    x = point_at(aux, r, b1, b2)
    wi, t = unit_or_zero((x[0] - p[0], x[1] - p[1], x[2] - p[2]))
    cos_l = _cos_light(I, li, aux, r, wi)
    den = aux[r + T_AREA] * cos_l
    pdf = prob * t * t / den if den != 0.0 else 0.0
    if not (cos_l > 0.0 and t > 0.0 and pdf > 0.0):
        return wi, 0.0, ZERO3, 0.0, tri
    le = emitted(I, li, aux, iaux, tx, tri, b0, b1, b2)
    inv = 1.0 / pdf
    return wi, t, (le[0] * inv, le[1] * inv, le[2] * inv), pdf, tri


@kernel
def pdf_hit_triangle(I, li, aux, o, d, t, tri):
    """Solid-angle pdf of ``sample(o)`` for the point o + t d on emitter triangle ``tri``."""
    if I[li, I_DIST_OFF] < 0 or tri < 0 or tri >= I[li, I_COUNT]:
        return 0.0
    r = I[li, I_TRI_OFF] + tri * TRI_STRIDE
    cos_l = _cos_light(I, li, aux, r, d)
    den = aux[r + T_AREA] * cos_l
    if not (cos_l > 0.0 and den != 0.0):
        return 0.0
    return _d.pmf_1d(aux, I[li, I_DIST_OFF], I[li, I_COUNT], tri) * t * t / den


@kernel
def eval_triangle(I, li, aux, d, tri):
    """Per-triangle radiance of ``tri`` seen along ray direction d (0 from behind a one-sided one)."""
    r = I[li, I_TRI_OFF] + tri * TRI_STRIDE
    c = -dot(d, aux3(aux, r + T_N))
    front = abs(c) > 0.0 if aux[r + T_TWO_SIDED] != 0.0 else c > 0.0
    return aux3(aux, r + T_RAD) if front else ZERO3
