"""The ``emission`` material (a black surface that emits) and the shared ``emission`` field.

Every material's parser calls :func:`parse_emission`, so any surface may also emit:
``"emission": [r, g, b]`` (texturable), radiance in W m⁻² sr⁻¹ from both sides (as Cycles), or
from the front only with the material's ``"emission_sides": "front"`` (read by the scene loader). The
``emission`` material itself has ``color`` × ``strength`` (Blender's Emission shader) and a black
BSDF (it reflects nothing, so next-event estimation and continuation are skipped).
"""
from __future__ import annotations

import numpy as np

from ..textures import ConstantParam, Param
from . import register
from .base import BSDF, BSDFSample, Material, NothingButDeltaBSDF, ShadingContext
from .common import as_param


class ScaledParam(Param):
    """An RGB Param times a constant factor (colour × strength)."""

    channels = 3

    def __init__(self, inner: Param, factor: float):
        self.inner = inner
        self.factor = float(factor)
        self.is_constant = inner.is_constant

    def bind(self, uv: np.ndarray) -> np.ndarray:
        return self.inner.bind(uv) * self.factor

    def mean(self) -> np.ndarray:
        return self.inner.mean() * self.factor

    def kernel_pack(self, packer, channels: int, factor):
        return packer.pack(self.inner, channels, factor * self.factor)


def scaled(param: Param, factor: float) -> Param:
    if isinstance(param, ConstantParam):
        return ConstantParam(param.value.reshape(3) * float(factor), 3)
    return ScaledParam(param, factor)


def emits(param: Param | None) -> bool:
    """False for a missing or constant-black emission (no mesh light is built for it)."""
    if param is None:
        return False
    if isinstance(param, ConstantParam):
        return bool(np.any(param.value > 0))
    return True


def parse_emission(node) -> Param | None:
    """The optional ``emission`` field every material accepts (RGB radiance, texturable)."""
    if not node.has("emission"):
        node.ignore("emission")
        return None
    p = node.param("emission", channels=3, lo=0.0, color=True)
    return p if emits(p) else None


class BlackBSDF(NothingButDeltaBSDF):
    """Reflects and transmits nothing. Every query returns zeros; sample() ends the path."""

    # No lobes at all: "every lobe is a delta" holds vacuously, which makes the integrator skip
    # next-event estimation for these lanes (it would only multiply by 0).
    has_delta = False

    def sample(self, wi, rng, mode=0):
        n = wi.shape[0]
        wo = np.zeros((n, 3))
        wo[:, 2] = np.where(wi[:, 2] < 0, -1.0, 1.0)
        return BSDFSample(wo, np.zeros((n, 3)), np.zeros(n), np.zeros(n, dtype=bool))

    def albedo(self):
        return np.zeros((1, 3))


class EmissionMaterial(Material):
    type_name = "emission"
    textured_params = ("color",)
    two_sided = True

    def __init__(self, color=1.0, strength: float = 1.0):
        self.color = as_param(color, 3)
        self.strength = float(strength)
        e = scaled(self.color, self.strength)
        self.emission = e if emits(e) else None

    def bind(self, ctx: ShadingContext) -> BSDF:
        return BlackBSDF(ctx.n)

    def pack(self, row) -> None:
        from ..kernels import materials as km
        row.kind = km.BLACK



@register("emission")
def parse_emission_material(node) -> EmissionMaterial:
    color = node.param("color", [1.0, 1.0, 1.0], channels=3, lo=0.0, color=True)
    strength = node.number("strength", 1.0, lo=0.0)
    return EmissionMaterial(color, strength)

