"""Per-triangle tables of the triangle soup, built in one pass per triangle.

The soup stores what embree traces: float32 corners (positions, shading normals, UVs). Shading
needs, per triangle, the corners and the geometric frame in one place (``shading_rows``) and,
for the loader, the frame in float64 (``triangle_frames``). Computing those with NumPy made
float64 copies of every corner array and ~10 temporaries (1 M triangles: 1.8 s and ~0.5 GB);
here each triangle reads its float32 corners once and writes its row. Hit points are recomputed
from barycentrics in float64 (geometry/accel.py: the ray offset only covers float32 vertex
error).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel


# Shading rows: everything the shading kernel reads of a hit triangle, in one 128-byte float32
# row (two cache lines) instead of eight arrays. Measured on the Cornell box (18k triangles, a
# ~4 MB working set): cache misses on the triangle tables cost 40-50 ns of a ~120 ns lane; one
# packed row roughly halves the lines touched per hit. float32 loses nothing for the corners,
# shading normals and UVs (the soup stores them in float32; the kernel interpolates in float64,
# and the difference of two float32 values is exact in float64); the geometric normal and the
# UV tangent are rounded to float32 (a direction error below 1e-7 rad).
ROW_V = 0            # 9: corners 0, 1, 2 (x, y, z)
ROW_N = 9            # 9: shading normals at the corners (zeros without normals)
ROW_UV = 18          # 6: UVs at the corners (zeros without UVs)
ROW_NG = 24          # 3: unit geometric normal (CCW winding)
ROW_TAN = 27         # 3: unit UV tangent dP/du (zeros where undefined)
ROW_MAT = 30         # int32 (through the int32 view): material index
ROW_EMIT = 31        # int32: local triangle index of the mesh light, −1 if it does not emit
ROW_SIZE = 32


@kernel(nogil=True)
def _fill_shading_rows(v, n, has_n, uv, has_uv, ng, tan, material, emitter, rows, irows):
    for t in range(v.shape[0]):
        for c in range(3):
            for j in range(3):
                rows[t, ROW_V + 3 * c + j] = v[t, c, j]
                rows[t, ROW_N + 3 * c + j] = n[t, c, j] if has_n else np.float32(0.0)
            for j in range(2):
                rows[t, ROW_UV + 2 * c + j] = uv[t, c, j] if has_uv else np.float32(0.0)
        for j in range(3):
            rows[t, ROW_NG + j] = ng[t, j]
            rows[t, ROW_TAN + j] = tan[t, j]
        irows[t, ROW_MAT] = material[t]
        irows[t, ROW_EMIT] = emitter[t]


def shading_rows(vertices, normals, uvs, geo_normal, tangent, material, emitter):
    """(rows float32 (T, ROW_SIZE), irows: the same memory as int32) for T ≥ 1 triangles; a
    scene without triangles gets one zero row (the kernel never reads it)."""
    T = vertices.shape[0]
    rows = np.zeros((max(T, 1), ROW_SIZE), np.float32)
    irows = rows.view(np.int32)
    if T:
        f32 = lambda a: np.ascontiguousarray(a, np.float32)  # noqa: E731
        dummy = np.zeros((1, 3, 3), np.float32)
        _fill_shading_rows(f32(vertices), f32(normals) if normals is not None else dummy, normals is not None,
                           f32(uvs) if uvs is not None else dummy[:, :, :2].copy(), uvs is not None,
                           f32(geo_normal), f32(tangent), np.ascontiguousarray(material, np.int32),
                           np.ascontiguousarray(emitter, np.int32), rows, irows)
    return rows, irows


@kernel(nogil=True)
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
            # dP/du from the UV differences (anisotropy follows the UV map, docs/architecture.md).
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


@kernel(nogil=True)
def _fill_nondegenerate(positions, indices, keep):
    for t in range(indices.shape[0]):
        a, b, c = indices[t, 0], indices[t, 1], indices[t, 2]
        scale = 0.0
        for k in (a, b, c):
            for j in range(3):
                scale = max(scale, abs(np.float64(positions[k, j])))
        scale = max(scale, 1e-30)
        x0, y0, z0 = np.float64(positions[a, 0]), np.float64(positions[a, 1]), np.float64(positions[a, 2])
        e1x, e1y, e1z = np.float64(positions[b, 0]) - x0, np.float64(positions[b, 1]) - y0, np.float64(positions[b, 2]) - z0
        e2x, e2y, e2z = np.float64(positions[c, 0]) - x0, np.float64(positions[c, 1]) - y0, np.float64(positions[c, 2]) - z0
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        # Relative threshold: below float32 resolution the triangle has no usable normal.
        keep[t] = math.sqrt(nx * nx + ny * ny + nz * nz) > (scale * scale) * 1e-12


def nondegenerate(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(T,) bool: the indexed triangles whose doubled area, in float64 from the float32 corners,
    exceeds 1e-12 × the square of their largest coordinate magnitude."""
    keep = np.empty(indices.shape[0], np.bool_)
    if indices.shape[0]:
        _fill_nondegenerate(np.ascontiguousarray(positions, np.float32),
                            np.ascontiguousarray(indices, np.int32), keep)
    return keep
