"""Emissive triangles (objects whose material has ``emission``), for next-event estimation.

The integrator builds one ``MeshLight`` from all emissive triangles of the scene (world space,
float64) with one radiance per triangle, used to pick triangles; a textured emission picks by its
value at the triangle's UV centroid, and the sample's value is the exact texture lookup at the
sampled point (``radiance_at``), so next-event estimation stays unbiased.
The integrator intersects the triangles through embree (they are ordinary scene geometry), so this
class provides sampling and the MIS density ``pdf_hit_triangle`` only.

Scenes use ``two_sided=True``: Cycles' emission shader emits from both faces (measured with
Cycles 5.0.1). One-sided emission (the counter-clockwise front only) remains available.

Sampling: a triangle with probability ∝ area × luminance(radiance), then a uniform point on it
(Heitz's low-distortion square-to-triangle map); pdf in solid angle = P(tri) / area × t² / |cos|.
"""
from __future__ import annotations

import numpy as np

from ..mathutil import cross, dot, luminance
from ..sampling.discrete import Discrete1D
from ..sampling.warp import square_to_triangle_barycentric
from .base import Light, LightSample
from .common import safe_div


class MeshLight(Light):
    def __init__(self, triangles_world: np.ndarray, radiance: np.ndarray, two_sided: bool = False,
                 radiance_at=None):
        """``radiance_at(tri, bary)`` (optional) gives the exact radiance at sampled points
        (textured emission): tri (n,) triangle indices, bary (n, 3) weights of v0, v1, v2. Without
        it the per-triangle ``radiance`` is used; with it, ``radiance`` only steers sampling."""
        self.radiance_at = radiance_at
        v = np.asarray(triangles_world, dtype=np.float64).reshape(-1, 3, 3)
        self.v0 = v[:, 0]
        self.e1 = v[:, 1] - v[:, 0]
        self.e2 = v[:, 2] - v[:, 0]
        n = cross(self.e1, self.e2)
        length = np.linalg.norm(n, axis=1)
        self.area = 0.5 * length
        self.normal = n / np.where(length > 0, length, 1.0)[:, None]
        self.radiance = np.broadcast_to(np.asarray(radiance, dtype=np.float64).reshape(-1, 3), (v.shape[0], 3)).copy()
        self.two_sided = bool(two_sided)
        # Where the emitters are, for light selection (lights/selection.py): the area-weighted
        # centre and the radius of the sphere around it that holds every vertex.
        centroids = v.mean(axis=1)
        total_area = float(self.area.sum())
        self.position = (centroids * self.area[:, None]).sum(axis=0) / total_area if total_area > 0 else centroids.mean(axis=0)
        self.extent = float(np.linalg.norm(v.reshape(-1, 3) - self.position, axis=1).max()) if v.size else 0.0
        weight = self.area * np.maximum(luminance(self.radiance), 0.0)
        weight = np.where(np.isfinite(weight), weight, 0.0)
        self._total = float(weight.sum())
        self.select = Discrete1D(weight) if self._total > 0 else None
        self.pmf = self.select.pmf if self.select is not None else np.zeros(v.shape[0])

    @property
    def count(self) -> int:
        return int(self.area.shape[0])

    def power(self) -> float:
        # A Lambertian emitter radiates π L per unit area and side.
        return np.pi * self._total * (2.0 if self.two_sided else 1.0)

    def sample(self, p, u) -> LightSample:
        n = p.shape[0]
        if self.select is None:
            return LightSample(np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)), np.zeros(n))
        tri, prob, u_rem = self.select.sample(u[:, 0])
        bary = square_to_triangle_barycentric(np.stack([u_rem, u[:, 1]], axis=-1))
        # The warp returns two barycentrics (b0, b1); the point is b0·v0 + b1·v1 + (1−b0−b1)·v2.
        b0, b1 = bary[:, 0], bary[:, 1]
        x = self.v0[tri] + b1[:, None] * self.e1[tri] + (1.0 - b0 - b1)[:, None] * self.e2[tri]
        v = x - p
        t = np.sqrt(dot(v, v))
        wi = v / np.where(t > 0, t, 1.0)[:, None]
        cos_l = -dot(wi, self.normal[tri])
        if self.two_sided:
            cos_l = np.abs(cos_l)
        pdf = safe_div(prob * t * t, self.area[tri] * cos_l)
        ok = (cos_l > 0) & (t > 0) & (pdf > 0)
        if self.radiance_at is not None:
            emitted = self.radiance_at(tri, np.stack([b0, b1, 1.0 - b0 - b1], axis=-1))
        else:
            emitted = self.radiance[tri]
        value = np.where(ok[:, None], emitted * safe_div(1.0, pdf)[:, None], 0.0)
        return LightSample(wi, np.where(ok, t, 0.0), value, np.where(ok, pdf, 0.0))

    def pdf_hit_triangle(self, o, d, t, tri_index) -> np.ndarray:
        """Solid-angle pdf of ``sample(o)`` for the point o + t d on triangle ``tri_index``."""
        tri = np.asarray(tri_index, dtype=np.int64)
        cos_l = -dot(d, self.normal[tri])
        if self.two_sided:
            cos_l = np.abs(cos_l)
        pdf = safe_div(self.pmf[tri] * t * t, self.area[tri] * cos_l)
        return np.where(cos_l > 0, pdf, 0.0)

    def eval_triangle(self, d, tri_index) -> np.ndarray:
        """Radiance of triangle ``tri_index`` seen along ray direction d (per-triangle value)."""
        tri = np.asarray(tri_index, dtype=np.int64)
        cos_l = -dot(d, self.normal[tri])
        front = (np.abs(cos_l) > 0) if self.two_sided else (cos_l > 0)
        return np.where(front[:, None], self.radiance[tri], 0.0)
