"""Point lights, as Cycles ≥ 4.0 (src/scene/light.cpp, src/kernel/light/point.h).

Units: the scene gives Blender's ``energy`` P [W]. With radius 0 the light is a delta light of
radiant intensity I = P/(4π) W/sr. With radius r > 0 the emitter has radiance
L = P/(4π² r²) W m⁻² sr⁻¹ (a sphere of that radiance emits exactly P), in one of Blender's two
shapes (``use_soft_falloff``):

* sphere (``soft_falloff`` false): a real sphere, sampled uniformly in the cone it subtends. A
  shading point inside the sphere sees radiance L from every direction; it is sampled uniformly
  over the sphere of directions (Cycles samples a cosine hemisphere around the normal there; our
  interface has no normal, any valid pdf gives the same expectation).
* soft falloff (Blender's default): a disk of radius r centred on the light and facing the
  shading point, sampled by area. Far away it equals the sphere; close by, its irradiance is
  I/(d² + r²) instead of I/d², hence the name.

A directional factor (spot cone, IES profile) multiplies the emission along the direction the
light travels, in the light's local frame — see ``PointLight.directional_factor``. A profile is a
callable ``profile(local_dirs (n, 3)) -> (n,)``; if it has ``mean_factor(matrix, weight)`` that
gives its exact mean over the world sphere for light selection. Inside a sphere
light Cycles applies no directional factor, and neither do we.
"""
from __future__ import annotations

import numpy as np

from ..mathutil import Frame, cross, dot, normalize
from ..sampling.warp import square_to_disk_concentric, square_to_uniform_sphere
from . import register
from .base import Light, LightSample
from .common import (column, cone_pdf, parse_common, power_luminance, ray_sphere, safe_div,
                     sample_cone, sin2_to_one_minus_cos)

INV_4PI = 0.25 / np.pi


class PointLight(Light):
    """Point / sphere / soft-falloff disk light. ``profile(local_dirs) -> (n,)`` is optional."""

    def __init__(self, to_world: np.ndarray, power: float, color, radius: float = 0.0,
                 soft_falloff: bool = False, visible_camera: bool = False, profile=None):
        self.to_world = np.asarray(to_world, dtype=np.float64)
        self.position = column(self.to_world, 3)
        self.color = np.asarray(color, dtype=np.float64).reshape(3)
        self.watts = float(power)
        self.radius = float(radius)
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
    def local_direction(self, w_out: np.ndarray) -> np.ndarray:
        """Unit directions in the light object's local frame (it shines towards local −Z)."""
        return normalize(w_out @ self._to_local.T)

    def directional_factor(self, w_out: np.ndarray) -> np.ndarray | None:
        """Factor on the emission travelling along world directions ``w_out``; None means 1."""
        if self.profile is None:
            return None
        return np.asarray(self.profile(self.local_direction(w_out)), dtype=np.float64)

    def _emit(self, base: np.ndarray, w_out: np.ndarray, apply: np.ndarray | None = None) -> np.ndarray:
        """base (3,) × factor(w_out) per lane; ``apply`` masks the lanes that get the factor."""
        out = np.broadcast_to(base, (w_out.shape[0], 3)).copy()
        f = self.directional_factor(w_out)
        if f is not None:
            if apply is not None:
                f = np.where(apply, f, 1.0)
            out *= f[:, None]
        return out

    def _mean_factor(self, z_lo: float = -1.0, breaks=()) -> float:
        """Mean directional factor over the world sphere of directions (light selection only).

        Quadrature over local directions l with z' = −l_z in [z_lo, 1] (the spot cone, or the whole
        sphere), Gauss-Legendre in z' on each piece between ``breaks`` (kinks of the factor); the
        solid-angle Jacobian of the object's linear map is |det M| / |M l|³.
        """
        if self.directional_factor(np.array([[0.0, 0.0, -1.0]])) is None:
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

    # ------------------------------------------------------------------ sampling
    def sample(self, p: np.ndarray, u: np.ndarray) -> LightSample:
        if self.is_delta:
            return self._sample_delta(p)
        if self.is_sphere:
            return self._sample_sphere(p, u)
        return self._sample_disk(p, u)

    def _sample_delta(self, p):
        v = self.position - p
        d2 = dot(v, v)
        dist = np.sqrt(d2)
        wi = normalize(v)
        value = self._emit(self.intensity, -wi) * safe_div(1.0, d2)[:, None]   # I / d²
        return LightSample(wi, dist, value, np.zeros(p.shape[0]))

    def _cones(self, d2: np.ndarray):
        """Per lane: (outside the sphere?, 1 − cos of the sphere's cone, use the spread cone?)."""
        r2 = self.radius * self.radius
        outside = d2 > r2
        omc_sphere = sin2_to_one_minus_cos(safe_div(r2, d2))
        use_spread = np.zeros(d2.shape, dtype=bool)
        if self._spread_one_minus_cos is not None:
            use_spread = outside & (self._spread_one_minus_cos < omc_sphere)
        return outside, omc_sphere, use_spread

    def _sample_sphere(self, p, u):
        n = p.shape[0]
        oc = p - self.position
        d2 = dot(oc, oc)
        to_center = normalize(-oc)
        outside, omc_sphere, use_spread = self._cones(d2)
        axis = to_center
        omc = omc_sphere
        if use_spread.any():
            axis = np.where(use_spread[:, None], self._spread_axis[None, :], to_center)
            omc = np.where(use_spread, self._spread_one_minus_cos, omc_sphere)
        wi = np.where(outside[:, None], sample_cone(axis, omc, u), square_to_uniform_sphere(u))
        pdf = np.where(outside, cone_pdf(omc), INV_4PI)
        t = self._sphere_distance(oc, wi, outside, must_hit=~use_spread)
        ok = np.isfinite(t)
        value = self._emit(self.radiance, -wi, apply=outside) * safe_div(1.0, pdf)[:, None]
        value[~ok] = 0.0
        return LightSample(wi, np.where(ok, t, 0.0), value, np.where(ok, pdf, 0.0))

    def _sphere_distance(self, oc, wi, outside, must_hit):
        """Distance along unit wi from o (oc = o − centre) to the sphere; inf on a miss.

        The discriminant uses the perpendicular distance |oc × wi| (no cancellation); directions
        drawn inside the sphere's cone always hit, so rounding at the silhouette is clamped there.
        """
        r2 = self.radius * self.radius
        b = dot(oc, wi)
        perp = cross(oc, wi)
        disc = r2 - dot(perp, perp)
        miss = (disc < 0) & ~must_hit
        sq = np.sqrt(np.maximum(disc, 0.0))
        t = np.where(outside, -b - sq, -b + sq)
        miss |= t <= 0
        return np.where(miss, np.inf, t)

    def _sample_disk(self, p, u):
        oc = p - self.position
        d2 = dot(oc, oc)
        light_n = normalize(oc)                       # disk normal, facing the shading point
        frame = Frame.from_normal_tangent(light_n)
        disk = square_to_disk_concentric(u) * self.radius
        x = self.position + frame.to_world(np.concatenate([disk, np.zeros((p.shape[0], 1))], axis=1))
        v = x - p
        t = np.sqrt(dot(v, v))
        wi = normalize(v)
        cos_l = dot(light_n, -wi)
        pdf = safe_div(t * t, np.pi * self.radius ** 2 * cos_l)
        ok = (cos_l > 0) & (t > 0) & (d2 > 0)
        value = self._emit(self.radiance, -wi) * safe_div(1.0, pdf)[:, None]
        value[~ok] = 0.0
        return LightSample(wi, t, value, np.where(ok, pdf, 0.0))

    # ------------------------------------------------------------------ hits (MIS)
    def intersect(self, o, d, tmax):
        if self.is_delta:
            return np.full(o.shape[0], np.inf)
        if self.is_sphere:
            return ray_sphere(o, d, self.position, self.radius, tmax)
        oc = o - self.position
        dist = np.sqrt(dot(oc, oc))
        light_n = normalize(oc)
        denom = dot(d, light_n)
        t = safe_div(dist, -denom)
        x = o + t[:, None] * d - self.position
        hit = (denom < 0) & (dist > 0) & (t < tmax) & (dot(x, x) <= self.radius ** 2)
        return np.where(hit, t, np.inf)

    def eval_hit(self, o, d, t):
        if self.is_delta:
            return np.zeros((o.shape[0], 3))
        outside = None
        if self.is_sphere:
            oc = o - self.position
            outside = dot(oc, oc) > self.radius ** 2
        return self._emit(self.radiance, -d, apply=outside)

    def pdf_hit(self, o, d, t):
        if self.is_delta:
            return np.zeros(o.shape[0])
        oc = o - self.position
        d2 = dot(oc, oc)
        if self.is_sphere:
            outside, omc_sphere, use_spread = self._cones(d2)
            pdf = np.where(outside, cone_pdf(omc_sphere), INV_4PI)
            if use_spread.any():
                inside_cone = (1.0 - dot(d, self._spread_axis)) <= self._spread_one_minus_cos
                pdf = np.where(use_spread, np.where(inside_cone, cone_pdf(self._spread_one_minus_cos), 0.0), pdf)
            return pdf
        light_n = normalize(oc)
        cos_l = dot(light_n, -d)
        return np.where(cos_l > 0, safe_div(t * t, np.pi * self.radius ** 2 * cos_l), 0.0)


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
