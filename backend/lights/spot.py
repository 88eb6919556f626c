"""Spot lights, as Cycles ≥ 4.0 (src/scene/light.cpp, src/kernel/light/spot.h).

A spot light is a point light (point.py: same units, radius, soft falloff) whose emission is
multiplied by Cycles' cone falloff (smoothstep of the cosine to the cone axis, evaluated on the
travel direction in the light object's local frame, so a non-uniformly scaled spot has an
elliptical cone): per-lane code in ``backend/kernels/lights/spot.py``, whose docstring has the
formula. An optional profile (IES) multiplies the attenuation.

Sampling: like Cycles, a sphere spot light seen from close by samples the (larger) cone of the
spot instead of the sphere's visible cone when that is narrower: directions outside the spot cone
carry no light anyway. This class computes that cone's world half-angle (load time).
"""
from __future__ import annotations

import numpy as np

from ..kernels.lights import batch as _batch
from ..kernels.lights import point as _kp
from . import register
from .common import column, power_luminance, sin2_to_one_minus_cos, unit
from .point import PointLight, parse_point_fields


def spot_attenuation(cos_axis: np.ndarray, cos_half_angle: float, spot_smooth: float) -> np.ndarray:
    """Cycles' spot falloff of the local cosine to the cone axis (kernels/lights/spot.py).

    ``spot_smooth`` = 1/((1 − cos_half_angle) · spot_blend); ``np.inf`` for a hard edge.
    """
    z = np.asarray(cos_axis, dtype=np.float64)
    flat = np.ascontiguousarray(z).reshape(-1)
    out = np.empty(flat.size)
    _batch.spot_attenuation(flat, float(cos_half_angle), float(spot_smooth), out)
    return out.reshape(z.shape)


def spot_smooth_factor(cos_half_angle: float, blend: float) -> float:
    den = (1.0 - cos_half_angle) * blend
    return 1.0 / den if den > 0 else np.inf


class SpotLight(PointLight):
    def __init__(self, to_world, power, color, spot_size: float, spot_blend: float,
                 radius: float = 0.0, soft_falloff: bool = False, visible_camera: bool = False,
                 profile=None):
        """``spot_size``: full cone angle in radians; ``spot_blend`` in [0, 1]."""
        super().__init__(to_world, power, color, radius, soft_falloff, visible_camera, profile)
        half = 0.5 * float(spot_size)
        self.spot_size = float(spot_size)
        self.spot_blend = float(spot_blend)
        self.cos_half = float(np.cos(half))
        self.spot_smooth = spot_smooth_factor(self.cos_half, self.spot_blend)
        # World half-angle of the widest part of the (possibly elliptical) cone: tan scales with
        # the object's x/y scale over its z scale.
        su, sv, sw = (float(np.linalg.norm(column(self.to_world, i))) for i in range(3))
        tan_wide = np.tan(half) * max(su, sv) / sw if half < 0.5 * np.pi else np.inf
        sin2_wide = 1.0 if not np.isfinite(tan_wide) else tan_wide ** 2 / (1.0 + tan_wide ** 2)
        self._spread_one_minus_cos = sin2_to_one_minus_cos(sin2_wide)
        self._spread_axis = unit(column(self.to_world, 2))   # towards the light from lit points

    def _has_factor(self) -> bool:
        return True

    def _has_cone(self) -> bool:
        return True

    def _pack_spot(self, row) -> None:
        row.i[_kp.I_SPOT] = 1
        row.f[_kp.P_COS_HALF] = self.cos_half
        row.f[_kp.P_SPOT_SMOOTH] = self.spot_smooth

    def power(self) -> float:
        mean = self._profile_mean(
            lambda local: spot_attenuation(-local[:, 2], self.cos_half, self.spot_smooth))
        if mean is None:
            kink = self.cos_half + (1.0 - self.cos_half) * self.spot_blend   # end of the smoothstep
            mean = self._mean_factor(self.cos_half, (kink,))
        return power_luminance(self.color, self.watts) * mean


@register("spot")
def parse_spot(node) -> SpotLight:
    fields = parse_point_fields(node)
    size = node.number("spot_size", 45.0, lo=1.0, hi=180.0)
    blend = node.number("spot_blend", 0.15, lo=0.0, hi=1.0)
    return SpotLight(spot_size=np.radians(size), spot_blend=blend, **fields)
