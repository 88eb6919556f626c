"""Warps from uniform random numbers in [0, 1)^2 to directions/points, with their densities.

All functions are vectorised over rows: ``u`` has shape (N, 2). Densities are w.r.t. solid angle
(directions) or area (points). Each warp has a matching ``*_pdf`` so tests can chi-square them.
"""
from __future__ import annotations

import numpy as np

INV_PI = 1.0 / np.pi
INV_4PI = 0.25 / np.pi


def square_to_disk_concentric(u: np.ndarray) -> np.ndarray:
    """Shirley–Chiu concentric map to the unit disk; returns (N, 2)."""
    a = 2.0 * u[:, 0] - 1.0
    b = 2.0 * u[:, 1] - 1.0
    use_a = np.abs(a) > np.abs(b)
    r = np.where(use_a, a, b)
    safe_a = np.where(a == 0, 1.0, a)
    safe_b = np.where(b == 0, 1.0, b)
    phi = np.where(use_a, (np.pi / 4) * (b / safe_a), np.pi / 2 - (np.pi / 4) * (a / safe_b))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)


def square_to_cosine_hemisphere(u: np.ndarray) -> np.ndarray:
    """Malley's method with the polar disk map (r = √u0, φ = 2π·u1), z = √(1 − u0).

    For independent random u the polar map is as good as the concentric one and cheaper: one
    trigonometric call, sin φ = ±√(1 − cos²φ) (absolute error ≤ 1e-8 near φ = 0, π; the result
    stays unit length to rounding). The pdf is cos θ / π either way.
    """
    r = np.sqrt(u[:, 0])
    c = np.cos(2.0 * np.pi * u[:, 1])
    s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
    out = np.empty((u.shape[0], 3))
    out[:, 0] = r * c
    out[:, 1] = np.where(u[:, 1] < 0.5, r * s, -(r * s))
    out[:, 2] = np.sqrt(np.maximum(0.0, 1.0 - u[:, 0]))
    return out


def cosine_hemisphere_pdf(w: np.ndarray) -> np.ndarray:
    return np.maximum(w[:, 2], 0.0) * INV_PI


def square_to_uniform_sphere(u: np.ndarray) -> np.ndarray:
    z = 1.0 - 2.0 * u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def uniform_sphere_pdf(w: np.ndarray) -> np.ndarray:
    return np.full(w.shape[0], INV_4PI)


def square_to_uniform_cone(u: np.ndarray, cos_max: np.ndarray | float) -> np.ndarray:
    """Uniform directions within angle acos(cos_max) of +z."""
    cos_t = 1.0 - u[:, 0] * (1.0 - cos_max)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)


def uniform_cone_pdf(cos_max: np.ndarray | float) -> np.ndarray | float:
    return 1.0 / (2.0 * np.pi * (1.0 - cos_max))


def square_to_triangle_barycentric(u: np.ndarray) -> np.ndarray:
    """Uniform barycentrics (b1, b2) on a triangle (Heitz 2019 low-distortion map), shape (N, 2)."""
    u0, u1 = u[:, 0], u[:, 1]
    first = u0 <= u1
    b0 = np.where(first, u0 / 2.0, u0 - u1 / 2.0)
    b1 = np.where(first, u1 - b0, u1 / 2.0)
    # The map returns (b0, b1) with b0 + b1 <= 1; both uniform over the triangle.
    return np.stack([b0, b1], axis=-1)
