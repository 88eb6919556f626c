"""Sun (distant) light per lane, as Cycles ≥ 4.0 (src/scene/light.cpp, src/kernel/light/distant.h).

``strength`` is Blender's sun ``energy``: the irradiance E [W/m²] on a surface facing the sun.
The light travels along the object's local −Z, so the sun is seen towards local +Z.

* ``angle`` = 0: a delta light, E × colour on a facing surface.
* ``angle`` > 0 (angular diameter): a disk of directions of half-angle a = angle/2 with uniform
  radiance L = E / (π sin² a) (Cycles: ``eval_fac = 1/(π sin²(angle/2))``), so the irradiance of
  a surface that sees the whole disk is E cos θ. It is sampled uniformly in that cone, and rays
  escaping the scene inside the cone see it (``eval_escaped``), with MIS.

Precision: the cone is kept as 1 − cos a = 2 sin²(a/2) (computed at load time, float64), never
as cos a: for the real sun (a = 0.27°, 1 − cos a ≈ 1.1e-5) cos a would keep only ~11 significant
digits of the cone's size; sampling draws 1 − cos θ directly (warp.uniform_cone_local).
"""
from __future__ import annotations

from ..jit import kernel
from ..vec import dot
from .common import FIRST, I_FIRST, INF, ZERO3, get3, sample_cone

SUN = 3            # kind code (unique within the family: dispatch.py KINDS): distant light, delta or a disk of directions

S_DIR = FIRST            # 3: unit, towards the sun (local +Z)
S_IRRADIANCE = FIRST + 3     # 3: colour × E [W/m²]
S_RADIANCE = FIRST + 6   # 3: E/(π sin² a) × colour [W m⁻² sr⁻¹] (angle > 0)
S_OMC = FIRST + 9        # 1 − cos a
S_PDF = FIRST + 10       # 1/(2π(1 − cos a)) [1/sr]
I_DELTA = I_FIRST        # 1: angle 0


@kernel
def sample(P, I, li, u0, u1):
    axis = get3(P, li, S_DIR)
    if I[li, I_DELTA] != 0:
        return axis, INF, get3(P, li, S_IRRADIANCE), 0.0
    wi = sample_cone(axis, P[li, S_OMC], u0, u1)
    pdf = P[li, S_PDF]
    inv = 1.0 / pdf
    return wi, INF, (P[li, S_RADIANCE] * inv, P[li, S_RADIANCE + 1] * inv, P[li, S_RADIANCE + 2] * inv), pdf


@kernel
def _inside(P, li, d):
    return (1.0 - dot(d, get3(P, li, S_DIR))) <= P[li, S_OMC]


@kernel
def eval_escaped(P, I, li, d):
    if I[li, I_DELTA] != 0 or not _inside(P, li, d):
        return ZERO3
    return get3(P, li, S_RADIANCE)


@kernel
def pdf_escaped(P, I, li, d):
    if I[li, I_DELTA] != 0 or not _inside(P, li, d):
        return 0.0
    return P[li, S_PDF]
