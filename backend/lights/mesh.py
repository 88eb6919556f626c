"""Emissive triangles (objects whose material has ``emission``), for next-event estimation.

The scene loader builds one ``MeshLight`` from all emissive triangles of the scene (world space,
float64) with one radiance per triangle, used to pick triangles (a textured emission picks by its
value at the triangle's UV centroid). Given the triangles' UV corners, their emission parameters
(``emission``, one Param per material slot) and each triangle's slot, the sample's value is the
exact emission at the sampled point (the packed parameter evaluated at the interpolated UV), so
next-event estimation stays unbiased. The integrator intersects the triangles through embree
(they are ordinary scene geometry), so this class provides sampling and the MIS density
``pdf_hit_triangle`` only.

Scenes emit from both faces by default (Cycles' emission shader does, measured with Cycles
5.0.1); ``two_sided`` is a flag or one flag per triangle, False = the counter-clockwise front only
(a material's ``"emission_sides": "front"``).

Sampling (a triangle ∝ area × luminance, then a uniform point by Heitz's map; pdf in solid angle
P(tri)/area × t²/|cos|) is per-lane code in ``backend/kernels/lights/mesh.py``; this class
computes the per-triangle geometry and the selection weights (load time) and packs them.
"""
from __future__ import annotations

import numpy as np

from ..kernels.lights import batch as _batch
from ..kernels.lights import mesh as _km
from ..mathutil import cross, luminance
from ..sampling.discrete import Discrete1D
from .base import Light


class MeshLight(Light):
    def __init__(self, triangles_world: np.ndarray, radiance: np.ndarray, two_sided=False,
                 uvs: np.ndarray | None = None, emission: list | None = None,
                 slots: np.ndarray | None = None):
        """``radiance`` (n, 3) or (3,): per-triangle radiance [W m⁻² sr⁻¹]. For textured emission
        also ``uvs`` (n, 3, 2) UV corners, ``emission`` (Params, one per slot) and ``slots`` (n,)
        each triangle's index into ``emission``: samples then carry the exact emission at their
        UV, and ``radiance`` only steers sampling."""
        v = np.asarray(triangles_world, dtype=np.float64).reshape(-1, 3, 3)
        self.v0 = v[:, 0]
        self.e1 = v[:, 1] - v[:, 0]
        self.e2 = v[:, 2] - v[:, 0]
        n = cross(self.e1, self.e2)
        length = np.linalg.norm(n, axis=1)
        self.area = 0.5 * length
        self.normal = n / np.where(length > 0, length, 1.0)[:, None]
        self.radiance = np.broadcast_to(np.asarray(radiance, dtype=np.float64).reshape(-1, 3), (v.shape[0], 3)).copy()
        # Per triangle: both faces emit (True) or the front only (False).
        self.two_sided = np.broadcast_to(np.asarray(two_sided, dtype=bool).reshape(-1), (v.shape[0],)).copy()
        self.textured = emission is not None
        if self.textured:
            if uvs is None or slots is None:
                raise ValueError("textured mesh emission needs uvs, emission and slots")
            self.uvs = np.asarray(uvs, dtype=np.float64).reshape(-1, 3, 2)
            self.emission = list(emission)
            self.slots = np.asarray(slots, dtype=np.int64).reshape(-1)
        # Where the emitters are, for light selection (lights/selection.py): the area-weighted
        # centre and the radius of the sphere around it that holds every vertex.
        centroids = v.mean(axis=1)
        total_area = float(self.area.sum())
        self.position = (centroids * self.area[:, None]).sum(axis=0) / total_area if total_area > 0 else centroids.mean(axis=0)
        self.extent = float(np.linalg.norm(v.reshape(-1, 3) - self.position, axis=1).max()) if v.size else 0.0
        weight = self.area * np.maximum(luminance(self.radiance), 0.0)
        weight = np.where(np.isfinite(weight), weight, 0.0)
        self._total = float(weight.sum())
        self._sided_total = float((weight * np.where(self.two_sided, 2.0, 1.0)).sum())
        self.select = Discrete1D(weight) if self._total > 0 else None
        self.pmf = self.select.pmf if self.select is not None else np.zeros(v.shape[0])

    @property
    def count(self) -> int:
        return int(self.area.shape[0])

    def power(self) -> float:
        # A Lambertian emitter radiates π L per unit area and side.
        return np.pi * self._sided_total

    def pack(self, b) -> None:
        row = b.light(_km.MESH)
        row.select_point(self.position, self.extent)
        tris = np.concatenate([self.v0, self.e1, self.e2, self.normal, self.area[:, None], self.radiance,
                               self.two_sided[:, None].astype(np.float64)], axis=1)
        assert tris.shape[1] == _km.TRI_STRIDE
        row.i[_km.I_TRI_OFF] = b.aux(tris)
        row.i[_km.I_COUNT] = self.count
        row.i[_km.I_DIST_OFF] = b.aux(self.select.block) if self.select is not None else -1
        row.i[_km.I_TEXTURED] = int(self.textured)
        if self.textured:
            row.i[_km.I_UV_OFF] = b.aux(self.uvs.reshape(-1, 6))
            row.i[_km.I_SLOT_OFF] = b.iaux(self.slots)
            packed = [b.packer.pack(param, 3) for param in self.emission]
            row.i[_km.I_EMIT_OFF] = b.aux(np.array([values for values, _ in packed]).reshape(-1))
            row.i[_km.I_EMIT_TEX_OFF] = b.iaux(np.array([tex for _, tex in packed], np.int64))

    def pdf_hit_triangle(self, o, d, t, tri_index) -> np.ndarray:
        """Solid-angle pdf of ``sample(o)`` for the point o + t d on triangle ``tri_index``."""
        o = np.ascontiguousarray(o, dtype=np.float64).reshape(-1, 3)
        d = np.ascontiguousarray(d, dtype=np.float64).reshape(-1, 3)
        n = o.shape[0]
        t = np.ascontiguousarray(np.broadcast_to(np.asarray(t, dtype=np.float64).reshape(-1), (n,)))
        tri = np.ascontiguousarray(np.broadcast_to(np.asarray(tri_index, dtype=np.int64).reshape(-1), (n,)))
        out = np.empty(n)
        _batch.mesh_pdf_hit(self.kernel_table()[0], np.zeros(1, np.int64), o, d, t, tri, out)
        return out

    def eval_triangle(self, d, tri_index) -> np.ndarray:
        """Radiance of triangle ``tri_index`` seen along ray direction d (per-triangle value)."""
        d = np.ascontiguousarray(d, dtype=np.float64).reshape(-1, 3)
        tri = np.ascontiguousarray(np.broadcast_to(np.asarray(tri_index, dtype=np.int64).reshape(-1), (d.shape[0],)))
        out = np.empty((d.shape[0], 3))
        _batch.mesh_eval(self.kernel_table()[0], np.zeros(1, np.int64), d, tri, out)
        return out
