"""Per-triangle tables of the triangle soup, built in one pass per triangle.

The soup stores what embree traces: float32 corners (positions, shading normals, UVs). Shading
needs, per triangle, float64 interpolation rows and the geometric frame. Computing those with
NumPy made float64 copies of every corner array and ~10 temporaries (1 M triangles: 1.8 s and
~0.5 GB); here each triangle reads its float32 corners once and writes its rows. float64 because
hit points are recomputed from barycentrics in float64 (geometry/accel.py: the ray offset only
covers float32 vertex error), and the difference of two float32 corners is exact in float64.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, _nrt=False)
def _fill_rows(c, out):
    """out[t] = (c0, c1 − c0, c2 − c0) in float64; c (T, 3, k) float32, out (T, 3k)."""
    k = c.shape[2]
    for t in range(c.shape[0]):
        for j in range(k):
            a = np.float64(c[t, 0, j])
            out[t, j] = a
            out[t, k + j] = np.float64(c[t, 1, j]) - a
            out[t, 2 * k + j] = np.float64(c[t, 2, j]) - a


def interpolation_rows(corners: np.ndarray) -> np.ndarray:
    """(T, 3k) float64 rows: corner 0, then the differences to corners 1 and 2 (what the shading
    kernel interpolates with barycentrics)."""
    out = np.empty((corners.shape[0], 3 * corners.shape[2]))
    if corners.shape[0]:
        _fill_rows(np.ascontiguousarray(corners, np.float32), out)
    return out


@njit(cache=True, nogil=True, _nrt=False)
def _fill_frames(v, uv, has_uv, geo_normal, tangent, area):
    for t in range(v.shape[0]):
        x0, y0, z0 = np.float64(v[t, 0, 0]), np.float64(v[t, 0, 1]), np.float64(v[t, 0, 2])
        e1x, e1y, e1z = np.float64(v[t, 1, 0]) - x0, np.float64(v[t, 1, 1]) - y0, np.float64(v[t, 1, 2]) - z0
        e2x, e2y, e2z = np.float64(v[t, 2, 0]) - x0, np.float64(v[t, 2, 1]) - y0, np.float64(v[t, 2, 2]) - z0
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        ln = math.sqrt(nx * nx + ny * ny + nz * nz)
        area[t] = 0.5 * ln
        s = 1.0 / ln if ln > 0.0 else 1.0            # zero normals stay zero (no NaN)
        geo_normal[t, 0], geo_normal[t, 1], geo_normal[t, 2] = nx * s, ny * s, nz * s
        tx = ty = tz = 0.0
        if has_uv:
            # dP/du from the UV differences (anisotropy follows the UV map, DESIGN.md §3).
            u0, w0 = np.float64(uv[t, 0, 0]), np.float64(uv[t, 0, 1])
            du1, dv1 = np.float64(uv[t, 1, 0]) - u0, np.float64(uv[t, 1, 1]) - w0
            du2, dv2 = np.float64(uv[t, 2, 0]) - u0, np.float64(uv[t, 2, 1]) - w0
            det = du1 * dv2 - du2 * dv1
            if abs(det) > 1e-20:
                inv = 1.0 / det
                px = (e1x * dv2 - e2x * dv1) * inv
                py = (e1y * dv2 - e2y * dv1) * inv
                pz = (e1z * dv2 - e2z * dv1) * inv
                lp = math.sqrt(px * px + py * py + pz * pz)
                if lp > 0.0:
                    tx, ty, tz = px / lp, py / lp, pz / lp
        tangent[t, 0], tangent[t, 1], tangent[t, 2] = tx, ty, tz


def triangle_frames(vertices: np.ndarray, uvs: np.ndarray | None):
    """(geo_normal (T, 3), tangent (T, 3), area (T,)), float64: unit geometric normal (CCW
    winding; zero for degenerate triangles), unit UV tangent dP/du (zero without UVs or where the
    UV map is degenerate), area in square scene units."""
    T = vertices.shape[0]
    geo_normal, tangent, area = np.empty((T, 3)), np.empty((T, 3)), np.empty(T)
    if T:
        v = np.ascontiguousarray(vertices, np.float32)
        uv = np.ascontiguousarray(uvs, np.float32) if uvs is not None else np.zeros((1, 3, 2), np.float32)
        _fill_frames(v, uv, uvs is not None, geo_normal, tangent, area)
    return geo_normal, tangent, area
