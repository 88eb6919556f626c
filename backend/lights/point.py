"""Point lights, as Cycles ≥ 4.0 (src/scene/light.cpp, src/kernel/light/point.h).

Units: the scene gives Blender's ``energy`` P [W]. With radius 0 the light is a delta light of
radiant intensity I = P/(4π) W/sr. With radius r > 0 the emitter has radiance
L = P/(4π² r²) W m⁻² sr⁻¹ in one of Blender's two shapes (``use_soft_falloff``): a sphere, or a
disk of radius r facing the shading point (soft falloff, Blender's default). The shapes, their
sampling and the directional factor are per-lane code in ``backend/kernels/lights/point.py``
(its docstring has the details); this class parses, converts units, estimates the power for light
selection and packs the light's table row.

A directional factor (spot cone, IES profile) multiplies the emission along the direction the
light travels, in the light's local frame. The optional ``profile`` is an IES profile
(``backend.ies.light.IESEmission``: the compiled kernels evaluate IES tables, not arbitrary
callables); its ``mean_factor(matrix, weight)`` gives its exact mean over the world sphere for
light selection.
"""
from __future__ import annotations

import numpy as np

from ..kernels.lights import batch as _batch
from ..kernels.lights import point as _kp
from . import register
from .base import Light
from .common import column, parse_common, power_luminance

from ..kernels.consts import INV_4PI


class PointLight(Light):
    """Point / sphere / soft-falloff disk light with an optional IES ``profile`` (IESEmission)."""

    def __init__(self, to_world: np.ndarray, power: float, color, radius: float = 0.0,
                 soft_falloff: bool = False, visible_camera: bool = False, profile=None):
        self.to_world = np.asarray(to_world, dtype=np.float64)
        self.position = column(self.to_world, 3)
        self.color = np.asarray(color, dtype=np.float64).reshape(3)
        self.watts = float(power)
        # A sphere so small that r² underflows (below ~1e-150 m) is the point light it looks like.
        self.radius = float(radius) if float(radius) ** 2 > 1e-280 else 0.0
        self.soft_falloff = bool(soft_falloff)
        self.profile = profile
        self._linear = self.to_world[:3, :3]
        self._to_local = np.linalg.inv(self._linear)
        self.intensity = self.color * self.watts * INV_4PI                  # W/sr, radius 0
        r = self.radius
        self.radiance = (self.color * self.watts / (4.0 * np.pi ** 2 * r * r)) if r > 0 else np.zeros(3)
        self.is_delta = r <= 0.0
        self.is_hittable = r > 0.0
        self.visible_camera = bool(visible_camera) and r > 0.0
        self.is_sphere = r > 0.0 and not self.soft_falloff
        # A spot light narrows the set of directions worth sampling (see spot.py).
        self._spread_axis = None
        self._spread_one_minus_cos = None

    # ------------------------------------------------------------------ emission profile
    def _has_factor(self) -> bool:
        return self.profile is not None

    def directional_factor(self, w_out: np.ndarray) -> np.ndarray | None:
        """Factor on the emission travelling along world directions ``w_out``; None means 1."""
        if not self._has_factor():
            return None
        w = np.ascontiguousarray(w_out, dtype=np.float64).reshape(-1, 3)
        out = np.empty(w.shape[0])
        _batch.directional_factor(self.kernel_table()[0], 0, w, out)
        return out

    def _mean_factor(self, z_lo: float = -1.0, breaks=()) -> float:
        """Mean directional factor over the world sphere of directions (light selection only).

        Quadrature over local directions l with z' = −l_z in [z_lo, 1] (the spot cone, or the whole
        sphere), Gauss-Legendre in z' on each piece between ``breaks`` (kinks of the factor); the
        solid-angle Jacobian of the object's linear map is |det M| / |M l|³.
        """
        if not self._has_factor():
            return 1.0
        xn, xw = np.polynomial.legendre.leggauss(48)
        edges = np.unique(np.clip([z_lo, *breaks, 1.0], z_lo, 1.0))
        z = np.concatenate([0.5 * (b - a) * xn + 0.5 * (a + b) for a, b in zip(edges[:-1], edges[1:])])
        wz = np.concatenate([0.5 * (b - a) * xw for a, b in zip(edges[:-1], edges[1:])])
        nphi = 128
        phi = (np.arange(nphi) + 0.5) * (2.0 * np.pi / nphi)
        Z, PHI = np.meshgrid(z, phi, indexing="ij")
        W = np.broadcast_to(wz[:, None], Z.shape)
        s = np.sqrt(np.maximum(0.0, 1.0 - Z * Z))
        local = np.stack([s * np.cos(PHI), s * np.sin(PHI), -Z], axis=-1).reshape(-1, 3)
        world = local @ self._linear.T
        length = np.linalg.norm(world, axis=1)
        jac = abs(np.linalg.det(self._linear)) / np.maximum(length, 1e-300) ** 3
        f = self.directional_factor(world / length[:, None])
        mean = float(np.sum(f * jac * W.ravel()) * (2.0 * np.pi / nphi) / (4.0 * np.pi))
        # Not clamped to 1: an IES beam that concentrates flux has a mean factor of flux/177.83 lm.
        return max(mean, 0.0)

    def _profile_mean(self, weight=None):
        """A profile's own mean over the world sphere (``mean_factor(matrix, weight)``, exact for
        IES tables), or None when it has none."""
        mean_factor = getattr(self.profile, "mean_factor", None)
        if mean_factor is None:
            return None
        return max(float(mean_factor(self._linear, weight)), 0.0)

    def power(self) -> float:
        mean = self._profile_mean()
        return power_luminance(self.color, self.watts) * (mean if mean is not None else self._mean_factor())

    # ------------------------------------------------------------------ light table
    def pack(self, b) -> None:
        shape = (_kp.SHAPE_DELTA if self.is_delta else
                 _kp.SHAPE_SPHERE if self.is_sphere else _kp.SHAPE_DISK)
        row = b.light(_kp.POINT, delta=self.is_delta, hittable=self.is_hittable,
                      visible_camera=self.visible_camera)
        row.put(_kp.P_POS, self.position)
        if self.profile is not None or self._has_cone():
            from ..mathutil import luminance
            row.select_profile(self.position, self.radius,
                               max(float(luminance(self.color)), 0.0) * self.watts * INV_4PI)
        else:
            row.select_point(self.position, self.radius)
        row.put(_kp.P_INTENSITY, self.intensity)
        row.put(_kp.P_RADIANCE, self.radiance)
        row.f[_kp.P_RADIUS] = self.radius
        row.put(_kp.P_TO_LOCAL, self._to_local)
        row.i[_kp.I_SHAPE] = shape
        row.f[_kp.P_SPREAD_OMC] = -1.0
        if self._spread_one_minus_cos is not None:
            row.put(_kp.P_SPREAD_AXIS, self._spread_axis)
            row.f[_kp.P_SPREAD_OMC] = self._spread_one_minus_cos
        self._pack_spot(row)
        if self.profile is not None:
            from ..ies.light import IESEmission
            if not isinstance(self.profile, IESEmission):
                raise TypeError(f"point/spot light profiles must be IES profiles (IESEmission), "
                                f"got {type(self.profile).__name__}")
            prof = self.profile.profile
            row.i[_kp.I_IES_OFF] = b.aux(prof.block)
            row.i[_kp.I_IES_NH] = prof.nh
            row.i[_kp.I_IES_NV] = prof.nv
            row.i[_kp.I_IES_FLAGS] = prof.flags
            row.f[_kp.P_IES_SCALE] = self.profile.scale

    def _has_cone(self) -> bool:
        """Spot lights have a cone factor (spot.py)."""
        return False

    def _pack_spot(self, row) -> None:
        """Spot lights write their cone (spot.py)."""


# --------------------------------------------------------------------------- scene parser

def parse_profile(node):
    """The optional ``ies`` field of point/spot lights (backend/ies/light.py) or None."""
    if not node.has("ies"):
        return None
    from ..ies.light import parse_profile as parse_ies
    return parse_ies(node.child("ies"))


def parse_point_fields(node):
    to_world, color, visible_camera = parse_common(node)
    power = node.number("power", lo=0.0)
    radius = node.number("radius", 0.0, lo=0.0)
    soft = node.boolean("soft_falloff", False)
    return dict(to_world=to_world, power=power, color=color, radius=radius, soft_falloff=soft,
                visible_camera=visible_camera, profile=parse_profile(node))


@register("point")
def parse_point(node) -> PointLight:
    return PointLight(**parse_point_fields(node))
