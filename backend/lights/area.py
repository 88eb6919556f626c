"""Area lights (rectangle, square, disk, ellipse), as Cycles ≥ 4.0, plus directional area lights.

Geometry (src/scene/light.cpp): the emitter is centred on the object's origin, spans
``size`` × ``size_y`` along the object's local X and Y *including the object's scale* (Blender's
``Light.area(matrix_world=...)``), and emits from one side, towards local −Z. Shear is ignored
(the Y axis is orthogonalised against X).

Units: with ``normalize`` (default) the radiance scale is L0 = P / (π A_world), so a Lambertian
emitter radiates exactly P watts; without it L0 = P/π (Cycles' ``invarea`` = 1).

Angular profile (profiles.py), radiance = L0 · f(θ) / K, always emitting P in total:
* ``spread`` (Blender's area light spread, degrees, default 180): Cycles' soft-box falloff
  f = max(0, 1 − tan θ / tan(spread/2)). spread = 0 is Cycles' collimated limit: a delta light
  shining straight down the normal (``CollimatedAreaLight``).
* ``cutoff_angle`` / ``beam_width`` (degrees): the directional area light, smoothstep in angle.

Sampling for next-event estimation (only the part of the emitter that can reach the shading
point: the cutoff cone ∝ emitted power, the clipped box by spherical rectangle, or an ellipse by
area) and the MIS density that redoes the same choice are per-lane code in
``backend/kernels/lights/area.py``, whose docstring has the details; this class parses, converts
units, builds the cone table and packs the light's table row.
"""
from __future__ import annotations

import numpy as np

from ..kernels.lights import area as _ka
from ..kernels.lights import profiles as _kp
from ..mathutil import dot, outer3
from . import register
from .base import Light
from .common import column, parse_common, power_luminance, unit
from .profiles import ConeTable, CyclesSpread, Lambertian, SmoothCone

SHAPES = ("square", "rectangle", "disk", "ellipse")


class _Emitter:
    """Frame and size of a planar emitter built from ``to_world`` (shared by the two classes)."""

    def __init__(self, to_world, shape: str, size_u: float, size_v: float):
        m = np.asarray(to_world, dtype=np.float64)
        self.center = column(m, 3)
        self.position = self.center
        cu, cv = column(m, 0), column(m, 1)
        self.axis_u = unit(cu)
        self.axis_v = unit(cv - dot(cv, self.axis_u) * self.axis_u)
        self.normal = -unit(column(m, 2))           # emission direction (local −Z)
        self.len_u = float(np.linalg.norm(cu)) * float(size_u)
        self.len_v = float(np.linalg.norm(cv - dot(cv, self.axis_u) * self.axis_u)) * float(size_v)
        self.half_u = 0.5 * self.len_u
        self.half_v = 0.5 * self.len_v
        self.ellipse = shape in ("disk", "ellipse")
        self.area = self.len_u * self.len_v * (0.25 * np.pi if self.ellipse else 1.0)

    def pack(self, row) -> None:
        """The geometry columns (kernels/lights/area.py)."""
        row.put(_ka.A_CENTER, self.center)
        row.put(_ka.A_U, self.axis_u)
        row.put(_ka.A_V, self.axis_v)
        row.put(_ka.A_N, self.normal)
        row.f[_ka.A_HALF_U] = self.half_u
        row.f[_ka.A_HALF_V] = self.half_v
        row.f[_ka.A_AREA] = self.area
        row.i[_ka.I_ELLIPSE] = int(self.ellipse)


class AreaLight(Light):
    is_hittable = True

    def __init__(self, to_world, shape: str, size_u: float, size_v: float, power: float, color,
                 normalize: bool = True, profile=None, visible_camera: bool = False):
        self.geo = _Emitter(to_world, shape, size_u, size_v)
        self.position = self.geo.center
        self.color = np.asarray(color, dtype=np.float64).reshape(3)
        self.watts = float(power)
        self.normalize = bool(normalize)
        self.profile = profile if profile is not None else Lambertian()
        self.visible_camera = bool(visible_camera)
        area_term = self.geo.area if self.normalize else 1.0
        # L0 / K: the radiance scale including the profile's power normalisation.
        den = np.pi * area_term * self.profile.normalization
        self.radiance_scale = self.color * self.watts / den if den > 0 else np.zeros(3)
        self.emits = self.geo.area > 0 and self.watts > 0 and float(self.color.max()) > 0
        self.cone = ConeTable(self.profile) if np.isfinite(self.profile.tan_max) else None

    def power(self) -> float:
        if not self.emits:
            return 0.0
        return power_luminance(self.color, self.watts * (1.0 if self.normalize else self.geo.area))

    # ------------------------------------------------------------------ emission
    def radiance(self, cos_out: np.ndarray) -> np.ndarray:
        """Radiance leaving the emitter at cos θ to its normal (n, 3)."""
        return outer3(self.profile(cos_out), self.radiance_scale)

    # ------------------------------------------------------------------ light table
    def pack(self, b) -> None:
        g = self.geo
        row = b.light(_ka.AREA, hittable=True, visible_camera=self.visible_camera)
        # Light selection: one-sided, 0 behind the emitter (kernels/lights/selection.py).
        # A profile (spread, cutoff) concentrates the power: weighed by it towards the point.
        k = self.profile.normalization
        peak = 1.0 / k if self.profile.code != _kp.LAMBERTIAN and k > 0 else 0.0
        row.select_one_sided(g.center, g.normal, g.area, peak)
        g.pack(row)
        row.put(_ka.A_SCALE, self.radiance_scale)
        row.i[_ka.I_EMITS] = int(self.emits)
        self.profile.pack(row)
        if self.cone is not None:
            row.i[_ka.I_CONE_OFF] = b.aux(self.cone.block)
            row.i[_ka.I_CONE_BINS] = self.cone.bins
            row.f[_ka.A_MU_LO] = self.cone.mu_lo
            row.f[_ka.A_WIDTH] = self.cone.width


class CollimatedAreaLight(Light):
    """spread = 0: every point of the emitter shines only along its normal (a delta light).

    As Cycles, a point in front of the emitter whose projection falls on it receives the
    irradiance P/A × colour (P × colour without ``normalize``) from direction −normal.
    """

    is_delta = True

    def __init__(self, to_world, shape, size_u, size_v, power, color, normalize=True,
                 visible_camera=False):
        self.geo = _Emitter(to_world, shape, size_u, size_v)
        self.position = self.geo.center
        self.color = np.asarray(color, dtype=np.float64).reshape(3)
        self.watts = float(power)
        self.normalize = bool(normalize)
        self.visible_camera = False
        area_term = self.geo.area if self.normalize else 1.0
        self.irradiance = self.color * self.watts / area_term if area_term > 0 else np.zeros(3)

    def power(self) -> float:
        if self.geo.area <= 0:
            return 0.0
        return power_luminance(self.color, self.watts * (1.0 if self.normalize else self.geo.area))

    def pack(self, b) -> None:
        row = b.light(_ka.COLLIMATED, delta=True)
        row.select_point(self.geo.center, 0.0)
        self.geo.pack(row)
        row.put(_ka.A_SCALE, self.irradiance)
        row.i[_ka.I_EMITS] = int(self.geo.area > 0)
        row.f[_ka.A_TAN_MAX] = np.inf


# --------------------------------------------------------------------------- scene parser

def _pencil(half_angle_deg: float) -> bool:
    """A cone so narrow that float64 cannot tell it from a line (cos = 1, below ~1e-6°): it is
    the collimated limit (a width-0 cone table would divide by zero)."""
    return float(np.cos(np.radians(half_angle_deg))) >= 1.0


@register("area")
def parse_area(node):
    to_world, color, visible_camera = parse_common(node)
    shape = node.string("shape", "square", choices=SHAPES)
    size = node.number("size", 1.0, lo=0.0)
    size_y = node.number("size_y", size, lo=0.0)   # read for every shape: Blender always has it
    size_v = size_y if shape in ("rectangle", "ellipse") else size
    power = node.number("power", lo=0.0)
    normalize = node.boolean("normalize", True)
    spread = node.number("spread", 180.0, lo=0.0, hi=180.0)
    has_cone = node.has("cutoff_angle") or node.has("beam_width")
    if has_cone and spread < 180.0:
        raise node.fail("give either spread or cutoff_angle/beam_width, not both", "spread")
    if has_cone:
        cutoff = node.number("cutoff_angle", 90.0, lo=0.0, hi=90.0, lo_open=True)
        beam = node.number("beam_width", cutoff, lo=0.0, hi=90.0)
        if beam > cutoff:
            raise node.fail(f"expected a number <= cutoff_angle ({cutoff:g}), got {beam:g}", "beam_width")
        if _pencil(cutoff):
            return CollimatedAreaLight(to_world, shape, size, size_v, power, color, normalize)
        profile = SmoothCone(np.radians(cutoff), np.radians(beam))
    elif spread <= 0.0 or _pencil(0.5 * spread):
        return CollimatedAreaLight(to_world, shape, size, size_v, power, color, normalize)
    elif spread < 180.0:
        profile = CyclesSpread(np.radians(spread))
    else:
        profile = Lambertian()
    return AreaLight(to_world, shape, size, size_v, power, color, normalize, profile, visible_camera)
