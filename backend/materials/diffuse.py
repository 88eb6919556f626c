"""Lambertian reflection: f = color / π, cosine-weighted hemisphere sampling."""
from __future__ import annotations

import numpy as np

from ..kernels.lazy import lazy
from . import register
from .base import RADIANCE, ClosedFormBSDF, Material, ShadingContext, lanes, rows3, taken
from .common import as_param
from .emission import parse_emission


_batch = lazy("bsdf.batch")     # compiled on first use (kernels/lazy.py)


class DiffuseBSDF(ClosedFormBSDF):
    """Two-sided Lambertian (per-lane maths: backend/kernels/bsdf/diffuse.py)."""

    def __init__(self, n: int, color: np.ndarray):
        self.n = n
        self.color = color  # (1, 3) constant or (n, 3) textured, linear RGB albedo

    def _eval_pdf(self, wi, wo, mode=RADIANCE):
        wi, wo = rows3(wi), rows3(wo)
        f = np.empty((wi.shape[0], 3))
        pdf = np.empty(wi.shape[0])
        _batch.diffuse_eval_pdf(rows3(self.color), wi, wo, f, pdf)
        return f, pdf



    def _sample_into(self, wi, rng, mode, out):
        _batch.diffuse_sample(rows3(self.color), wi, rng.random((wi.shape[0], 2)), *out)

    def albedo(self):
        return self.color

    def take(self, idx):
        idx = np.asarray(idx)
        n = taken(idx)
        return DiffuseBSDF(n, lanes(self.color, idx))


class DiffuseMaterial(Material):
    type_name = "diffuse"
    textured_params = ("color",)
    two_sided = True

    def __init__(self, color=0.8, emission=None):
        self.color = as_param(color, 3)
        self.emission = emission

    def bind(self, ctx: ShadingContext) -> DiffuseBSDF:
        return DiffuseBSDF(ctx.n, self.color.bind(ctx.uv))

    def pack(self, row) -> None:
        from ..kernels import materials as km
        row.kind = km.DIFFUSE
        row.set(km.COLOR, self.color, 3)



@register("diffuse")
def parse_diffuse(node) -> DiffuseMaterial:
    color = node.param("color", [0.8, 0.8, 0.8], channels=3, lo=0.0, color=True)
    return DiffuseMaterial(color, emission=parse_emission(node))
