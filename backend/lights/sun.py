"""Sun (distant) light, as Cycles ≥ 4.0 (src/scene/light.cpp, src/kernel/light/distant.h).

``strength`` is Blender's sun ``energy``: the irradiance E [W/m²] on a surface facing the sun.
The light travels along the object's local −Z, so the sun is seen towards local +Z.

* ``angle`` = 0: a delta light, E × colour on a facing surface.
* ``angle`` > 0 (angular diameter): a disk of directions of half-angle a = angle/2 with uniform
  radiance L = E / (π sin² a) (Cycles: ``eval_fac = 1/(π sin²(angle/2))``), so the irradiance of
  a surface that sees the whole disk is E cos θ. It is sampled uniformly in that cone, and rays
  escaping the scene inside the cone see it (``eval_escaped``), with MIS.

Per-lane code: ``backend/kernels/lights/sun.py``. 1 − cos a is computed here as 2 sin²(a/2),
exact for tiny suns (see that module on precision).
"""
from __future__ import annotations

import numpy as np

from ..kernels.lights import sun as _ks
from . import register
from .base import Light
from .common import column, parse_common, power_luminance, unit


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
        # A disk too small for float64 (sin² a underflows, below ~1e-150 rad) is the delta sun.
        self.is_delta = half <= 0.0 or np.sin(half) ** 2 < 1e-280
        self.visible_camera = bool(visible_camera)
        self.irradiance = self.color * self.strength
        if not self.is_delta:
            # 1 − cos a = 2 sin²(a/2), exact for tiny suns.
            self.one_minus_cos = 2.0 * np.sin(0.5 * half) ** 2
            self.radiance = self.irradiance / (np.pi * np.sin(half) ** 2)
            self.pdf_value = 1.0 / (2.0 * np.pi * self.one_minus_cos)   # [1/sr]
        self.scene_radius = 1.0

    def prepare(self, scene_center, scene_radius):
        self.scene_radius = float(scene_radius)

    def power(self) -> float:
        # The flux through the scene's bounding disk (as pbrt-v4 for distant lights).
        return power_luminance(self.color, self.strength) * np.pi * self.scene_radius ** 2

    def pack(self, b) -> None:
        row = b.light(_ks.SUN, delta=self.is_delta, infinite=True, visible_camera=self.visible_camera)
        row.select_uniform()
        row.put(_ks.S_DIR, self.direction)
        row.put(_ks.S_IRRADIANCE, self.irradiance)
        row.i[_ks.I_DELTA] = int(self.is_delta)
        if not self.is_delta:
            row.put(_ks.S_RADIANCE, self.radiance)
            row.f[_ks.S_OMC] = self.one_minus_cos
            row.f[_ks.S_PDF] = self.pdf_value


@register("sun")
def parse_sun(node) -> SunLight:
    to_world, color, visible_camera = parse_common(node)
    strength = node.number("strength", lo=0.0)
    angle = node.number("angle", 0.0, lo=0.0, hi=180.0)
    return SunLight(to_world, strength, color, np.radians(angle), visible_camera)
