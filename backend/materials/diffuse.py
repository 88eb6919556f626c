"""Lambertian reflection: f = color / π, cosine-weighted hemisphere sampling."""
from __future__ import annotations

import numpy as np

from ..sampling.warp import square_to_cosine_hemisphere
from . import register
from .base import BSDF, BSDFSample, Material, ShadingContext, lanes
from .common import any_textured, as_param, times_color, upper_side
from .emission import parse_emission

INV_PI = 1.0 / np.pi


class DiffuseBSDF(BSDF):
    """Two-sided Lambertian: wi below the surface is handled by mirroring (see common.upper_side)."""

    def __init__(self, n: int, color: np.ndarray):
        self.n = n
        self.color = color  # (1, 3) constant or (n, 3) textured, linear RGB albedo

    def _cos_out(self, wi, wo):
        # Same side as wi, else 0 (no transmission).
        same = wi[:, 2] * wo[:, 2] > 0
        return np.where(same, np.abs(wo[:, 2]), 0.0)

    def eval(self, wi, wo, rng=None, mode=0):
        return times_color(INV_PI * self._cos_out(wi, wo), self.color)

    def pdf(self, wi, wo, rng=None, mode=0):
        return INV_PI * self._cos_out(wi, wo)

    def sample(self, wi, rng, mode=0):
        n = wi.shape[0]
        wo = square_to_cosine_hemisphere(rng.random((n, 2)))
        wo[:, 2] *= upper_side(wi)      # our own array: mirrored in place
        ok = (wi[:, 2] != 0) & (wo[:, 2] != 0)
        weight = times_color(ok, self.color)
        pdf = np.where(ok, INV_PI * np.abs(wo[:, 2]), 0.0)
        return BSDFSample(wo, weight, pdf, np.zeros(n, dtype=bool))

    def albedo(self):
        return self.color

    def take(self, idx):
        idx = np.asarray(idx)
        n = int(idx.sum()) if idx.dtype == bool else idx.size
        return DiffuseBSDF(n, lanes(self.color, idx))


class DiffuseMaterial(Material):
    type_name = "diffuse"
    two_sided = True

    def __init__(self, color=0.8, emission=None):
        self.color = as_param(color, 3)
        self.emission = emission

    def bind(self, ctx: ShadingContext) -> DiffuseBSDF:
        return DiffuseBSDF(ctx.n, self.color.bind(ctx.uv))

    @property
    def uses_textures(self) -> bool:
        return any_textured(self.color)


@register("diffuse")
def parse_diffuse(node) -> DiffuseMaterial:
    color = node.param("color", [0.8, 0.8, 0.8], channels=3, lo=0.0, color=True)
    return DiffuseMaterial(color, emission=parse_emission(node))
