"""Uniform sampling of the solid angle subtended by a rectangle (Ureña, Fajardo, King 2013,
"An Area-Preserving Parametrization for Spherical Rectangles"), vectorised over lanes.

Each lane has its own reference point o and rectangle (corner s, orthonormal edge directions ex,
ey, edge lengths lx, ly). The solid angle is computed from the four internal angles through
arcsin (as Cycles does) so small rectangles do not lose it to cancellation against 2π.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mathutil import cross, dot


@dataclass
class SphericalRect:
    o: np.ndarray
    x: np.ndarray      # (n, 3) unit edge direction of x
    y: np.ndarray
    z: np.ndarray      # (n, 3) unit, pointing from the rectangle's plane away from o
    x0: np.ndarray
    x1: np.ndarray
    y0: np.ndarray
    y1: np.ndarray
    z0: np.ndarray     # ≤ 0: signed distance of the plane along z
    b0: np.ndarray
    b1: np.ndarray
    g23: np.ndarray    # g2 + g3
    solid_angle: np.ndarray


def _asin(x):
    return np.arcsin(np.clip(x, -1.0, 1.0))


def spherical_rect(o, corner, ex, ey, lx, ly) -> SphericalRect:
    """Set up the spherical rectangle of the rectangle corner + [0, lx]·ex + [0, ly]·ey seen from o."""
    d = corner - o
    z = np.broadcast_to(cross(ex, ey), o.shape).copy()
    x0 = dot(d, ex)
    y0 = dot(d, ey)
    z0 = dot(d, z)
    flip = z0 > 0
    z[flip] = -z[flip]
    z0 = np.where(flip, -z0, z0)
    x1 = x0 + lx
    y1 = y0 + ly
    z2 = z0 * z0
    # z components of the four edge-plane normals, n_i = (…, …, c_i)/l_i.
    l0 = np.sqrt(z2 + y0 * y0)
    l1 = np.sqrt(z2 + x1 * x1)
    l2 = np.sqrt(z2 + y1 * y1)
    l3 = np.sqrt(z2 + x0 * x0)
    nz0 = -y0 / l0
    nz1 = x1 / l1
    nz2 = y1 / l2
    nz3 = -x0 / l3
    # γ_i = π/2 − g_i with g_i = asin(−n_i·n_{i+1}); S = Σγ_i − 2π = −Σg_i.
    g0 = _asin(-nz0 * nz1)
    g1 = _asin(-nz1 * nz2)
    g2 = _asin(-nz2 * nz3)
    g3 = _asin(-nz3 * nz0)
    solid = -(g0 + g1 + g2 + g3)
    return SphericalRect(o, np.broadcast_to(ex, o.shape), np.broadcast_to(ey, o.shape), z,
                         x0, x1, y0, y1, z0, nz0, nz2, g2 + g3, np.maximum(solid, 0.0))


def sample_spherical_rect(r: SphericalRect, u: np.ndarray) -> np.ndarray:
    """Points on the rectangle, uniformly distributed in solid angle (density 1/solid_angle)."""
    # Angle a_u = u·S + π + g2 + g3; the π flips the signs of both cos and sin and cancels in f_u.
    au = u[:, 0] * r.solid_angle + r.g23
    ca, sa = np.cos(au), np.sin(au)
    sa = np.where(np.abs(sa) > 1e-300, sa, 1e-300)
    fu = (ca * r.b0 + r.b1) / sa
    cu = np.clip(np.copysign(1.0, fu) / np.sqrt(fu * fu + r.b0 * r.b0), -1.0, 1.0)
    xu = -(cu * r.z0) / np.maximum(np.sqrt(np.maximum(1.0 - cu * cu, 0.0)), 1e-300)
    xu = np.clip(xu, r.x0, r.x1)
    dd = np.sqrt(xu * xu + r.z0 * r.z0)
    h0 = r.y0 / np.sqrt(dd * dd + r.y0 * r.y0)
    h1 = r.y1 / np.sqrt(dd * dd + r.y1 * r.y1)
    hv = h0 + u[:, 1] * (h1 - h0)
    hv2 = hv * hv
    yv = np.where(hv2 < 1.0 - 1e-12, hv * dd / np.sqrt(np.maximum(1.0 - hv2, 1e-300)), r.y1)
    yv = np.clip(yv, r.y0, r.y1)
    return r.o + xu[:, None] * r.x + yv[:, None] * r.y + r.z0[:, None] * r.z
