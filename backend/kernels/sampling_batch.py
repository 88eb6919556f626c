"""Array entry points of the per-lane sampling code (warp.py, discrete.py, spherical_rect.py) for
NumPy callers: ``backend/sampling/*.py`` loop these over lanes, so the warps, distributions and
the spherical-rectangle map have one implementation."""
from __future__ import annotations

from . import discrete as _d
from . import spherical_rect as _sr
from . import warp as _w
from .jit import kernel


@kernel
def sample_1d(block, n, u, idx, p, u_rem):
    for i in range(u.shape[0]):
        idx[i], p[i], u_rem[i] = _d.sample_1d(block, 0, n, u[i])


@kernel
def sample_2d(block, h, w, u, xy, pdf):
    for i in range(u.shape[0]):
        xy[i, 0], xy[i, 1], pdf[i] = _d.sample_2d(block, 0, h, w, u[i, 0], u[i, 1])


@kernel
def pdf_2d(block, h, w, xy, out):
    for i in range(xy.shape[0]):
        out[i] = _d.pdf_2d(block, 0, h, w, xy[i, 0], xy[i, 1])


@kernel
def spherical_rect(x0, y0, z0, lx, ly, out):
    """out[i] = the 10 numbers of the lane's spherical rectangle (spherical_rect.py)."""
    for i in range(x0.shape[0]):
        r = _sr.spherical_rect(x0[i], y0[i], z0[i], lx[i], ly[i])
        for k in range(10):
            out[i, k] = r[k]


@kernel
def sample_spherical_rect(rects, u, xu, yv):
    for i in range(u.shape[0]):
        r = rects[i]
        sr = (r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9])
        xu[i], yv[i] = _sr.sample(sr, u[i, 0], u[i, 1])


@kernel
def disk_concentric(u, out):
    for i in range(u.shape[0]):
        out[i, 0], out[i, 1] = _w.disk_concentric(u[i, 0], u[i, 1])


@kernel
def cosine_hemisphere(u, out):
    for i in range(u.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = _w.cosine_hemisphere(u[i, 0], u[i, 1])


@kernel
def uniform_sphere(u, out):
    for i in range(u.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = _w.uniform_sphere(u[i, 0], u[i, 1])


@kernel
def uniform_cone(u, one_minus_cos, out):
    for i in range(u.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = _w.uniform_cone_local(u[i, 0], u[i, 1], one_minus_cos)


@kernel
def triangle_barycentric(u, out):
    for i in range(u.shape[0]):
        out[i, 0], out[i, 1] = _w.triangle_barycentric(u[i, 0], u[i, 1])
