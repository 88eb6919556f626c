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

Sampling for next-event estimation: only the part of the emitter that can reach the shading point
is sampled. A point at height h in front of the light receives light only from the disk of radius
h·tan(cutoff) around its projection; a point whose disk box misses the emitter gets no sample at
all (value 0, no shadow ray). Otherwise the smallest of these is sampled: the cutoff cone of
directions itself, ∝ the emitted power (``ConeTable``; its footprint is that disk), the disk's
bounding box clipped to the emitter, uniformly in solid angle (spherical-rectangle map), or a whole
ellipse by area. ``pdf_hit`` redoes the same choice, so MIS sees the exact density.
"""
from __future__ import annotations

from dataclasses import fields, replace

import numpy as np

from ..mathutil import dot, outer3
from ..sampling.spherical_rect import sample_spherical_rect, spherical_rect
from ..sampling.warp import square_to_disk_concentric
from . import register
from .base import Light, LightSample
from .common import column, parse_common, power_luminance, safe_div, unit
from .profiles import ConeTable, CyclesSpread, Lambertian, SmoothCone

SHAPES = ("square", "rectangle", "disk", "ellipse")
# Below this solid angle [sr] the spherical-rectangle map is no better than area sampling and
# its angles lose relative precision: sample by area instead.
MIN_SOLID_ANGLE = 1e-8

MODE_NONE, MODE_SPHRECT, MODE_AREA_RECT, MODE_ELLIPSE, MODE_CONE = 0, 1, 2, 3, 4


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
        self.corner = self.center - self.half_u * self.axis_u - self.half_v * self.axis_v
        # Rows of _local: the emitter's axes u, v and its normal. Rows of rect_basis: the frame of
        # the spherical-rectangle sampler, (u, v, u × v); normal_in_rect is the normal in it.
        self._local = np.stack([self.axis_u, self.axis_v, self.normal])
        self._local_center = self._local @ self.center
        self.rect_basis = np.stack([self.axis_u, self.axis_v, np.cross(self.axis_u, self.axis_v)])
        self.normal_in_rect = self.rect_basis @ self.normal
        self._corner_in_rect = self.rect_basis @ self.corner

    def local(self, x):
        """Coordinates of points x (n, 3) along u, v and the normal, relative to the centre.

        A 3×3 matrix product per batch, giving contiguous rows (the absolute rounding error,
        ~1e-16·|x|, is far below the float32 geometry's)."""
        rel = self._local @ x.T - self._local_center[:, None]
        return rel[0], rel[1], rel[2]

    def local_dir(self, d):
        """Components of directions d (n, 3) along u, v and the normal."""
        rel = self._local @ d.T
        return rel[0], rel[1], rel[2]

    def corner_offset(self, p):
        """Coordinates of corner − p in the spherical-rectangle frame (u, v, u × v)."""
        rel = self._corner_in_rect[:, None] - self.rect_basis @ p.T
        return rel[0], rel[1], rel[2]

    def rect_to_world(self, x, y, z):
        """World vectors (n, 3) with components (x, y, z) in the frame (u, v, u × v).

        Column by column: stacking then multiplying by the 3x3 basis measured 3-5x slower."""
        b = self.rect_basis
        out = np.empty((x.shape[0], 3))
        for c in range(3):
            out[:, c] = x * b[0, c] + y * b[1, c] + z * b[2, c]
        return out

    def point(self, lu, lv):
        """World points at emitter coordinates (lu, lv)."""
        return np.stack([lu, lv], axis=1) @ self._local[:2] + self.center

    def inside(self, lu, lv):
        if self.ellipse:
            return (safe_div(lu, self.half_u) ** 2 + safe_div(lv, self.half_v) ** 2) <= 1.0
        return (np.abs(lu) <= self.half_u) & (np.abs(lv) <= self.half_v)


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

    def received_power(self, p: np.ndarray, power: float) -> np.ndarray:
        """Light-selection weight at points p (lights/selection.py): the power over the
        hemisphere at the point's distance, × the emitter-side cosine; 0 behind the emitter,
        where a one-sided light cannot contribute."""
        g = self.geo
        rel = p - g.center
        d2 = dot(rel, rel)
        h = dot(rel, g.normal)
        cos_e = np.clip(h / np.sqrt(np.maximum(d2, 1e-300)), 0.0, 1.0)
        # Near the emitter the received scale saturates at its own area (no 1/d² blow-up).
        return np.where(h > 0, power * np.maximum(cos_e, 0.05) / (np.pi * np.maximum(d2, g.area)), 0.0)

    def power(self) -> float:
        if not self.emits:
            return 0.0
        return power_luminance(self.color, self.watts * (1.0 if self.normalize else self.geo.area))

    # ------------------------------------------------------------------ emission
    def radiance(self, cos_out: np.ndarray) -> np.ndarray:
        """Radiance leaving the emitter at cos θ to its normal (n, 3)."""
        return outer3(self.profile(cos_out), self.radiance_scale)

    # ------------------------------------------------------------------ sampling plan
    def _plan(self, p):
        """Per lane: sampling mode, the region (u0, u1, v0, v1 in the emitter frame) and the
        spherical rectangles of the MODE_SPHRECT lanes (``sr`` rows follow ``np.nonzero(mode ==
        MODE_SPHRECT)``) with their solid angles scattered into ``solid`` (0 elsewhere)."""
        g = self.geo
        n = p.shape[0]
        pu, pv, h = g.local(p)
        u0 = np.full(n, -g.half_u)
        u1 = np.full(n, g.half_u)
        v0 = np.full(n, -g.half_v)
        v1 = np.full(n, g.half_v)
        clipped = bool(np.isfinite(self.profile.tan_max))
        if clipped:
            # Only the disk of radius h·tan(cutoff) around the projection can reach p.
            rc = np.maximum(h, 0.0) * self.profile.tan_max
            u0 = np.maximum(u0, pu - rc)
            u1 = np.minimum(u1, pu + rc)
            v0 = np.maximum(v0, pv - rc)
            v1 = np.minimum(v1, pv + rc)
        valid = (h > 0) & (u1 > u0) & (v1 > v0) & self.emits
        mode = np.where(valid, MODE_SPHRECT, MODE_NONE)
        box = (u1 - u0) * (v1 - v0)
        if g.ellipse:
            # whole ellipse by area unless the cone's box is smaller
            mode = np.where(valid & ~(box < g.area), MODE_ELLIPSE, mode)
        if clipped:
            # The cone itself (sampled ∝ the emitted power) when its footprint disk is smaller
            # than the box the other modes would sample: no waste when it lies on the emitter.
            footprint = np.pi * rc * rc
            smaller = footprint < (np.minimum(box, g.area) if g.ellipse else box)
            mode = np.where(valid & smaller, MODE_CONE, mode)
        solid = np.zeros(n)
        idx = np.nonzero(mode == MODE_SPHRECT)[0]
        sr = None
        if idx.size:
            # corner (u0, v0) relative to p; only |z0| matters to the spherical rectangle
            sr = spherical_rect(u0[idx] - pu[idx], v0[idx] - pv[idx], -h[idx], u1[idx] - u0[idx], v1[idx] - v0[idx])
            solid[idx] = sr.solid_angle
            small = sr.solid_angle < MIN_SOLID_ANGLE
            mode[idx[small]] = MODE_AREA_RECT
            if small.any():
                keep = ~small
                sr = _take(sr, keep)
                solid[idx[small]] = 0.0
        return mode, pu, pv, u0, u1, v0, v1, sr, solid

    # ------------------------------------------------------------------ NEE
    def _whole_rectangle(self) -> bool:
        """The common case (rectangle, no cutoff cone): every lane samples the whole emitter."""
        return not self.geo.ellipse and not np.isfinite(self.profile.tan_max)

    def _sample_whole_rectangle(self, p, u) -> LightSample:
        """Fast path of ``sample`` for ``_whole_rectangle`` lights: no per-mode masking, and all
        per-lane maths on 1-D arrays in the spherical-rectangle frame (one change of basis in,
        one out)."""
        g = self.geo
        x0, y0, z0 = g.corner_offset(p)
        sr = spherical_rect(x0, y0, z0, g.len_u, g.len_v)
        xu, yv = sample_spherical_rect(sr, u)
        pdf_sa = safe_div(1.0, sr.solid_angle)
        small = sr.solid_angle < MIN_SOLID_ANGLE
        if small.any():
            # Tiny solid angles: uniform area sampling (see MIN_SOLID_ANGLE).
            xu = np.where(small, x0 + u[:, 0] * g.len_u, xu)
            yv = np.where(small, y0 + u[:, 1] * g.len_v, yv)
        # The sampled point relative to p is (xu, yv, z0) in the frame.
        t = np.sqrt(xu * xu + yv * yv + z0 * z0)
        inv_t = 1.0 / np.where(t > 0, t, 1.0)
        wx, wy, wz = xu * inv_t, yv * inv_t, z0 * inv_t
        nx, ny, nz = g.normal_in_rect
        cos_out = -(wx * nx + wy * ny + wz * nz)
        h = -(x0 * nx + y0 * ny + z0 * nz)           # height of p above the emitter
        if small.any():
            pdf_sa = np.where(small, safe_div(t * t, cos_out * g.area), pdf_sa)
        ok = (h > 0) & (t > 0) & (cos_out > 0) & (pdf_sa > 0) & self.emits
        scale = self.profile(np.where(ok, cos_out, 0.0)) * np.where(ok, safe_div(1.0, pdf_sa), 0.0)
        wi = g.rect_to_world(wx, wy, wz)
        return LightSample(wi, np.where(ok, t, 0.0), outer3(scale, self.radiance_scale), np.where(ok, pdf_sa, 0.0))

    def sample(self, p, u) -> LightSample:
        if self._whole_rectangle():
            return self._sample_whole_rectangle(p, u)
        n = p.shape[0]
        g = self.geo
        mode, pu, pv, u0, u1, v0, v1, sr, solid = self._plan(p)
        x = np.zeros((n, 3))
        pdf_sa = np.zeros(n)           # solid-angle pdf, computed below for area modes
        m = mode == MODE_SPHRECT
        if m.any():
            xu, yv = sample_spherical_rect(sr, u[m])
            x[m] = g.point(pu[m] + xu, pv[m] + yv)
            pdf_sa[m] = 1.0 / solid[m]
        m = mode == MODE_AREA_RECT
        if m.any():
            a = u0[m] + u[m, 0] * (u1[m] - u0[m])
            b = v0[m] + u[m, 1] * (v1[m] - v0[m])
            x[m] = g.center + a[:, None] * g.axis_u + b[:, None] * g.axis_v
        m = mode == MODE_ELLIPSE
        if m.any():
            dsk = square_to_disk_concentric(u[m])
            x[m] = g.center + (dsk[:, 0] * g.half_u)[:, None] * g.axis_u + (dsk[:, 1] * g.half_v)[:, None] * g.axis_v
        m = mode == MODE_CONE
        if m.any():
            # emission direction e at cos μ to the normal; the ray from p goes along −e
            mu, phi, pdf_sa[m] = self.cone.sample(u[m])
            s = np.sqrt(np.maximum(0.0, 1.0 - mu * mu))
            e = mu[:, None] * g.normal + (s * np.cos(phi))[:, None] * g.axis_u + (s * np.sin(phi))[:, None] * g.axis_v
            _, _, h = g.local(p[m])
            x[m] = p[m] - (h / mu)[:, None] * e
        v = x - p
        t = np.sqrt(dot(v, v))
        wi = v / np.where(t > 0, t, 1.0)[:, None]
        cos_out = -dot(wi, g.normal)
        area_pdf = self._area_pdf(mode, u0, u1, v0, v1)
        by_area = area_pdf > 0
        pdf_sa = np.where(by_area, safe_div(area_pdf * t * t, cos_out), pdf_sa)
        lu, lv, _ = g.local(x)
        ok = (mode != MODE_NONE) & (t > 0) & (cos_out > 0) & (pdf_sa > 0)
        # cone directions may miss the emitter; box samples of an ellipse may fall outside it
        ok &= np.where(mode == MODE_CONE, g.inside(lu, lv), True)
        if g.ellipse:
            ok &= g.inside(lu, lv)
        le = self.radiance(np.where(ok, cos_out, 0.0))
        value = np.where(ok[:, None], le * safe_div(1.0, pdf_sa)[:, None], 0.0)
        return LightSample(wi, np.where(ok, t, 0.0), value, np.where(ok, pdf_sa, 0.0))

    def _area_pdf(self, mode, u0, u1, v0, v1):
        """Area density of the area-sampling modes (0 for the others)."""
        rect_area = (u1 - u0) * (v1 - v0)
        out = np.where(mode == MODE_AREA_RECT, safe_div(1.0, rect_area), 0.0)
        if self.geo.ellipse:
            out = np.where(mode == MODE_ELLIPSE, 1.0 / self.geo.area, out)
        return out

    # ------------------------------------------------------------------ hits (MIS)
    def intersect(self, o, d, tmax):
        g = self.geo
        ou, ov, h = g.local(o)
        du, dv, denom = g.local_dir(d)
        t = safe_div(h, -denom)
        lu, lv = ou + t * du, ov + t * dv      # emitter coordinates of o + t·d
        hit = (denom < 0) & (h > 0) & (t > 0) & (t < tmax) & g.inside(lu, lv) & self.emits
        return np.where(hit, t, np.inf)

    def eval_hit(self, o, d, t):
        cos_out = -dot(d, self.geo.normal)
        return outer3(np.where(cos_out > 0, self.profile(cos_out), 0.0), self.radiance_scale)

    def pdf_hit(self, o, d, t):
        g = self.geo
        if self._whole_rectangle():
            solid = spherical_rect(*g.corner_offset(o), g.len_u, g.len_v).solid_angle
            cos_out = -dot(d, g.normal)
            pdf = np.where(solid < MIN_SOLID_ANGLE, safe_div(t * t, cos_out * g.area), safe_div(1.0, solid))
            _, _, h = g.local(o)
            return np.where((cos_out > 0) & (h > 0), pdf, 0.0)
        mode, _, _, u0, u1, v0, v1, _, solid = self._plan(o)
        x = o + t[:, None] * d
        lu, lv, _ = g.local(x)
        in_region = (lu >= u0) & (lu <= u1) & (lv >= v0) & (lv <= v1)
        cos_out = -dot(d, g.normal)
        pdf = np.zeros(o.shape[0])
        m = (mode == MODE_SPHRECT) & in_region
        if m.any():
            pdf[m] = 1.0 / solid[m]
        area_pdf = self._area_pdf(mode, u0, u1, v0, v1)
        by_area = (area_pdf > 0) & ((mode == MODE_ELLIPSE) | in_region)
        pdf = np.where(by_area, safe_div(area_pdf * t * t, cos_out), pdf)
        m = mode == MODE_CONE
        if m.any():
            pdf[m] = self.cone.pdf(cos_out[m])
        return np.where(cos_out > 0, pdf, 0.0)


def _take(sr, m):
    """The spherical rectangles of the lanes selected by m."""
    return replace(sr, **{f.name: getattr(sr, f.name)[m] for f in fields(sr)})


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

    def sample(self, p, u) -> LightSample:
        g = self.geo
        pu, pv, h = g.local(p)
        ok = (h > 0) & g.inside(pu, pv)
        n = p.shape[0]
        wi = np.broadcast_to(-g.normal, (n, 3)).copy()
        value = np.where(ok[:, None], self.irradiance, 0.0)
        return LightSample(wi, np.where(ok, h, 0.0), value, np.zeros(n))


# --------------------------------------------------------------------------- scene parser

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
        profile = SmoothCone(np.radians(cutoff), np.radians(beam))
    elif spread <= 0.0:
        return CollimatedAreaLight(to_world, shape, size, size_v, power, color, normalize)
    elif spread < 180.0:
        profile = CyclesSpread(np.radians(spread))
    else:
        profile = Lambertian()
    return AreaLight(to_world, shape, size, size_v, power, color, normalize, profile, visible_camera)
