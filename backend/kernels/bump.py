"""Bump mapping per lane (Blender's Bump node): a height field h(u, v) tilts a normal against
its surface gradient. Used by the integrator for a material's bump map (any frame: world) and by
the stack table for an interface's (the lane's shading frame).

With dP/du and dP/dv the surface's derivatives along its UV map (from the triangle's corners) and
n the normal to tilt, the surface gradients of u and v are (dP/dv × n)/D and (n × dP/du)/D,
D = dP/du · (dP/dv × n); the gradient of h is ∂h/∂u ∇u + ∂h/∂v ∇v, and the bumped normal
normalize(n − d·∇h) (d: the distance, negative when inverted), mixed with n by the strength k as
Cycles: normalize(n + k·(bumped − n)). float64: the derivatives of a fine UV map are small
differences of corner coordinates.
"""
from __future__ import annotations

import math

from .jit import kernel
from .vec import cross, dot


@kernel
def uv_derivatives(e1, e2, du1, dv1, du2, dv2):
    """(dP/du, dP/dv, ok) of a triangle with edges e1, e2 [m] from its first corner and UV
    differences (du1, dv1), (du2, dv2) along them; ok False where the UVs are degenerate (no UV
    map on the triangle: nothing to bump along)."""
    det = du1 * dv2 - du2 * dv1
    if abs(det) < 1e-20:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), False
    dpdu = ((e1[0] * dv2 - e2[0] * dv1) / det, (e1[1] * dv2 - e2[1] * dv1) / det,
            (e1[2] * dv2 - e2[2] * dv1) / det)
    dpdv = ((e2[0] * du1 - e1[0] * du2) / det, (e2[1] * du1 - e1[1] * du2) / det,
            (e2[2] * du1 - e1[2] * du2) / det)
    return dpdu, dpdv, True


@kernel
def tilt(n, dpdu, dpdv, gu, gv, distance, strength):
    """n bumped by a height of gradient (gu, gv) = (∂h/∂u, ∂h/∂v) times ``distance``, mixed by
    ``strength``; n itself where the frame is degenerate."""
    a = cross(dpdv, n)
    b = cross(n, dpdu)
    dd = dot(dpdu, a)
    if abs(dd) < 1e-30:
        return n
    s = distance / dd
    w = (n[0] - s * (gu * a[0] + gv * b[0]), n[1] - s * (gu * a[1] + gv * b[1]),
         n[2] - s * (gu * a[2] + gv * b[2]))
    w = _unit(w)
    if strength != 1.0:
        w = _unit((n[0] + strength * (w[0] - n[0]), n[1] + strength * (w[1] - n[1]),
                   n[2] + strength * (w[2] - n[2])))
    return w


@kernel
def _unit(w):
    ln = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    if not ln > 0.0:
        return w
    return (w[0] / ln, w[1] / ln, w[2] / ln)
