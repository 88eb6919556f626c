"""Shared pieces of the light modules: scene-field parsing and small vectorised geometry helpers.

Conventions (DESIGN.md §3): world space is Blender's; a light object shines down its local −Z;
``to_world`` is the object's ``matrix_world``. All maths is float64 over (n, 3) rows.
"""
from __future__ import annotations

import numpy as np

from ..mathutil import Frame, dot, luminance

IDENTITY = np.eye(4)


# --------------------------------------------------------------------------- scene fields

def parse_common(node, color_default=(1.0, 1.0, 1.0)):
    """The fields every light object has: ``to_world``, ``color``, ``visible_camera``."""
    to_world = node.matrix4("to_world")
    color = node.rgb("color", list(color_default))
    visible_camera = node.boolean("visible_camera", False)
    return to_world, color, visible_camera


def column(m: np.ndarray, i: int) -> np.ndarray:
    return np.asarray(m[:3, i], dtype=np.float64)


def unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v


def power_luminance(color: np.ndarray, watts: float) -> float:
    """Luminance of colour × watts, clamped at 0 (light selection only)."""
    return max(float(luminance(np.asarray(color, dtype=np.float64))) * float(watts), 0.0)


# --------------------------------------------------------------------------- geometry

def safe_div(a, b):
    """a / b with 0 where b == 0 (never NaN/Inf from a zero denominator)."""
    b = np.asarray(b, dtype=np.float64)
    ok = b != 0
    return np.where(ok, a / np.where(ok, b, 1.0), 0.0)


def sin2_to_one_minus_cos(s2: np.ndarray) -> np.ndarray:
    """1 − cos α from sin²α without cancellation for small angles (α ≤ 90°)."""
    s2 = np.clip(s2, 0.0, 1.0)
    return s2 / (1.0 + np.sqrt(1.0 - s2))


def sample_cone(axis: np.ndarray, one_minus_cos: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Uniform directions within a cone around unit ``axis`` (n, 3); pdf 1/(2π(1 − cos α))."""
    # z from 1 − cos (not cos) so tiny cones (a 0.5° sun) keep their precision.
    one_minus_z = u[:, 0] * one_minus_cos
    z = 1.0 - one_minus_z
    sin_t = np.sqrt(np.maximum(one_minus_z * (2.0 - one_minus_z), 0.0))
    phi = 2.0 * np.pi * u[:, 1]
    local = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), z], axis=-1)
    return Frame.from_normal_tangent(axis).to_world(local)


def cone_pdf(one_minus_cos: np.ndarray) -> np.ndarray:
    return safe_div(1.0, 2.0 * np.pi * np.asarray(one_minus_cos, dtype=np.float64))


def ray_sphere(o: np.ndarray, d: np.ndarray, center: np.ndarray, radius: float,
               tmax: np.ndarray) -> np.ndarray:
    """First t in (0, tmax) where o + t d meets the sphere (from outside or inside); inf if none."""
    oc = o - center
    b = dot(oc, d)
    c = dot(oc, oc) - radius * radius
    disc = b * b - c
    ok = disc >= 0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    # Numerically stable roots: q = −b − sign(b)√disc, t0 = q, t1 = c/q.
    q = -b - np.copysign(sq, b)
    t_a = q
    t_b = safe_div(c, q)
    t_near = np.minimum(t_a, t_b)
    t_far = np.maximum(t_a, t_b)
    t = np.where(t_near > 0, t_near, t_far)
    hit = ok & (t > 0) & (t < tmax)
    return np.where(hit, t, np.inf)


def fibonacci_sphere(n: int) -> np.ndarray:
    """n nearly uniform unit directions (deterministic; used for power estimates)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
