"""Warps from uniform random numbers in [0, 1)^2 to directions/points, with their densities, on
arrays: each warp loops the per-lane code of ``backend/kernels/warp.py`` (one implementation).

``u`` has shape (N, 2). Densities are w.r.t. solid angle (directions) or area (points). Each warp
has a matching ``*_pdf`` so tests can chi-square them.
"""
from __future__ import annotations

import numpy as np

from ..kernels import sampling_batch as _b

from ..kernels.consts import INV_4PI, INV_PI


def _u(u):
    return np.ascontiguousarray(u, dtype=np.float64).reshape(-1, 2)


def _mapped(batch, u, width: int, *args) -> np.ndarray:
    """``batch(u, *args, out)`` over the (N, 2) numbers u into a new (N, width) array."""
    u = _u(u)
    out = np.empty((u.shape[0], width))
    batch(u, *args, out)
    return out


def square_to_disk_concentric(u: np.ndarray) -> np.ndarray:
    """Shirley–Chiu concentric map to the unit disk; returns (N, 2)."""
    return _mapped(_b.disk_concentric, u, 2)


def square_to_cosine_hemisphere(u: np.ndarray) -> np.ndarray:
    """Malley's method with the polar disk map (r = √u0, φ = 2π·u1), z = √(1 − u0); pdf cos θ/π."""
    return _mapped(_b.cosine_hemisphere, u, 3)


def cosine_hemisphere_pdf(w: np.ndarray) -> np.ndarray:
    return np.maximum(w[:, 2], 0.0) * INV_PI


def square_to_uniform_sphere(u: np.ndarray) -> np.ndarray:
    return _mapped(_b.uniform_sphere, u, 3)


def uniform_sphere_pdf(w: np.ndarray) -> np.ndarray:
    return np.full(w.shape[0], INV_4PI)


def square_to_uniform_cone(u: np.ndarray, cos_max: float) -> np.ndarray:
    """Uniform directions within angle acos(cos_max) of +z."""
    return _mapped(_b.uniform_cone, u, 3, 1.0 - float(cos_max))


def uniform_cone_pdf(cos_max: np.ndarray | float) -> np.ndarray | float:
    return 1.0 / (2.0 * np.pi * (1.0 - cos_max))


def square_to_triangle_barycentric(u: np.ndarray) -> np.ndarray:
    """Uniform barycentrics (b0, b1), b0 + b1 ≤ 1, on a triangle (Heitz 2019 low-distortion map),
    shape (N, 2)."""
    return _mapped(_b.triangle_barycentric, u, 2)
