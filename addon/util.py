"""Small helpers without bpy (colour, angles, matrices)."""
from __future__ import annotations

import math

import numpy as np


def srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4).astype(np.float32)


def degrees(radians: float) -> float:
    return round(math.degrees(radians), 6)


def f32(value) -> float:
    """A float32 Blender property as the shortest float that round-trips it (0.7, not 0.699999988)."""
    return float(f"{float(value):.7g}")


def rgb(value) -> list[float]:
    """First three channels of a colour as plain floats (drops alpha)."""
    return [f32(value[0]), f32(value[1]), f32(value[2])]


def matrix_rows(m) -> list[list[float]]:
    """A 4×4 (mathutils or numpy) as 4 rows of 4 floats, row-major (acts on column vectors)."""
    return [[float(m[r][c]) for c in range(4)] for r in range(4)]


def without_scale(m) -> np.ndarray:
    """Rotation + translation of an affine 4×4 (column lengths of the 3×3 set to 1, signs kept)."""
    a = np.array(m, dtype=np.float64).reshape(4, 4)
    lengths = np.linalg.norm(a[:3, :3], axis=0)
    a[:3, :3] /= np.where(lengths > 0, lengths, 1.0)
    return a


def f0_to_conductor_k(f0) -> list[float]:
    """k of a conductor with η = 1 whose normal-incidence reflectance is ``f0`` (per channel).

    With η = 1, F0 = k² / (4 + k²), so k = 2·sqrt(F0 / (1 − F0)); F0 is clamped below 1.
    """
    f = np.clip(np.asarray(f0, dtype=np.float64), 0.0, 0.999)
    return [round(float(v), 6) for v in 2.0 * np.sqrt(f / (1.0 - f))]
