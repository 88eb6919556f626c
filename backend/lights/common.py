"""Shared pieces of the light modules: scene-field parsing and load-time helpers.

Conventions (docs/architecture.md, Frames, units, precision): world space is Blender's; a light object shines down its local −Z;
``to_world`` is the object's ``matrix_world``. The per-lane geometry (cones, spheres, frames)
lives in ``backend/kernels/lights/``.
"""
from __future__ import annotations

import math

import numpy as np

from ..mathutil import luminance

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


def sin2_to_one_minus_cos(s2: float) -> float:
    """1 − cos α from sin²α without cancellation for small angles (α ≤ 90°)."""
    s2 = min(max(float(s2), 0.0), 1.0)
    return s2 / (1.0 + math.sqrt(1.0 - s2))
