"""Sun (distant) light, as Cycles ≥ 4.0 (src/scene/light.cpp, src/kernel/light/distant.h).

``strength`` is Blender's sun ``energy``: the irradiance E [W/m²] on a surface facing the sun.
The light travels along the object's local −Z, so the sun is seen towards local +Z.

* ``angle`` = 0: a delta light, E × colour on a facing surface.
* ``angle`` > 0 (angular diameter): a disk of directions of half-angle a = angle/2 with uniform
  radiance L = E / (π sin² a) (Cycles: ``eval_fac = 1/(π sin²(angle/2))``), so the irradiance of
  a surface that sees the whole disk is E cos θ. It is sampled uniformly in that cone, and rays
  escaping the scene inside the cone see it (``eval_escaped``), with MIS.
"""
from __future__ import annotations

import numpy as np

from ..mathutil import dot
from . import register
from .base import Light, LightSample
from .common import cone_pdf, column, parse_common, power_luminance, sample_cone, unit


class SunLight(Light):
    is_infinite = True

    def __init__(self, to_world, strength: float, color, angle: float = 0.0,
                 visible_camera: bool = False):
        """``angle``: angular diameter in radians."""
        self.direction = unit(column(np.asarray(to_world, dtype=np.float64), 2))  # towards the sun
        self.color = np.asarray(color, dtype=np.float64).reshape(3)
        self.strength = float(strength)
        self.angle = float(angle)
        half = 0.5 * self.angle
        self.is_delta = half <= 0.0
        self.visible_camera = bool(visible_camera)
        self.irradiance = self.color * self.strength
        if not self.is_delta:
            # 1 − cos a = 2 sin²(a/2), exact for tiny suns.
            self.one_minus_cos = 2.0 * np.sin(0.5 * half) ** 2
            self.radiance = self.irradiance / (np.pi * np.sin(half) ** 2)
            self.pdf_value = float(cone_pdf(self.one_minus_cos))
        self.scene_radius = 1.0

    def prepare(self, scene_center, scene_radius):
        self.scene_radius = float(scene_radius)

    def power(self) -> float:
        # The flux through the scene's bounding disk (as pbrt-v4 for distant lights).
        return power_luminance(self.color, self.strength) * np.pi * self.scene_radius ** 2

    def sample(self, p, u) -> LightSample:
        n = p.shape[0]
        dist = np.full(n, np.inf)
        if self.is_delta:
            wi = np.broadcast_to(self.direction, (n, 3)).copy()
            return LightSample(wi, dist, np.broadcast_to(self.irradiance, (n, 3)).copy(), np.zeros(n))
        axis = np.broadcast_to(self.direction, (n, 3))
        wi = sample_cone(axis, np.full(n, self.one_minus_cos), u)
        value = np.broadcast_to(self.radiance / self.pdf_value, (n, 3)).copy()
        return LightSample(wi, dist, value, np.full(n, self.pdf_value))

    def _inside(self, d):
        return (1.0 - dot(d, self.direction)) <= self.one_minus_cos

    def eval_escaped(self, d):
        if self.is_delta:
            return np.zeros((d.shape[0], 3))
        return np.where(self._inside(d)[:, None], self.radiance, 0.0)

    def pdf_escaped(self, d):
        if self.is_delta:
            return np.zeros(d.shape[0])
        return np.where(self._inside(d), self.pdf_value, 0.0)


@register("sun")
def parse_sun(node) -> SunLight:
    to_world, color, visible_camera = parse_common(node)
    strength = node.number("strength", lo=0.0)
    angle = node.number("angle", 0.0, lo=0.0, hi=180.0)
    return SunLight(to_world, strength, color, np.radians(angle), visible_camera)
