"""Uniform sampling of the solid angle subtended by a rectangle (Ureña, Fajardo, King 2013), on
arrays: loops the per-lane code of ``backend/kernels/spherical_rect.py`` (its docstring has the
frame conventions) over lanes. The area lights call the per-lane code directly."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import sampling_batch as _b


@dataclass
class SphericalRect:
    """Per lane: the rectangle [x0, x1] × [y0, y1] in the plane at signed distance z0 ≤ 0 (the
    frame's z axis mirrored where needed so the plane lies on its negative side)."""

    x0: np.ndarray
    x1: np.ndarray
    y0: np.ndarray
    y1: np.ndarray
    z0: np.ndarray     # ≤ 0: −(distance from the reference point to the plane)
    b0: np.ndarray
    b1: np.ndarray
    g23: np.ndarray    # g2 + g3
    solid_angle: np.ndarray
    c0: np.ndarray     # 1 − b0², without cancellation

    def rows(self) -> np.ndarray:
        return np.ascontiguousarray(np.stack([self.x0, self.x1, self.y0, self.y1, self.z0, self.b0,
                                              self.b1, self.g23, self.solid_angle, self.c0], axis=1))


def spherical_rect(x0, y0, z0, lx, ly) -> SphericalRect:
    """The spherical rectangles of corners (x0, y0, z0) + [0, lx]·ex + [0, ly]·ey seen from the
    origin (arrays broadcast together)."""
    x0, y0, z0, lx, ly = (np.ascontiguousarray(a, dtype=np.float64).ravel()
                          for a in np.broadcast_arrays(x0, y0, z0, lx, ly))
    out = np.empty((x0.size, 10))
    _b.spherical_rect(x0, y0, z0, lx, ly, out)
    return SphericalRect(*(out[:, k].copy() for k in range(10)))


def sample_spherical_rect(r: SphericalRect, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """In-plane coordinates (xu, yv) of points uniformly distributed in solid angle (density
    1/solid_angle) on the rectangles."""
    u = np.ascontiguousarray(u, dtype=np.float64).reshape(-1, 2)
    xu = np.empty(u.shape[0])
    yv = np.empty(u.shape[0])
    _b.sample_spherical_rect(r.rows(), u, xu, yv)
    return xu, yv
