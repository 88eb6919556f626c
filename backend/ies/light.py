"""IES light: a delta point emitter whose radiant intensity follows an LM-63 profile.

Units and frame as Cycles ≥ 4.0 (DESIGN.md §3): radiant intensity

    I(ω) [W/sr] = power [W] × candela(ω_local) / 177.83 × colour  (× spot cone for spot lights)

where ω_local = normalize(M⁻¹ ω) for the light's ``to_world`` 3×3 part M (the direction is taken to
object space as Cycles' IES node does with its "incoming" vector) and candela(·) is Cycles'
interpolation of the table (:mod:`backend.ies.profile`). A spot light multiplies Cycles' spot
attenuation smoothstep((cos − cos(size/2)) / ((1 − cos(size/2)) · blend)), cos = −ω_local.z.

Scene files: ``"ies": {"file": "lamp.ies"}`` (relative to the scene file) or
``{"data": "<LM-63 text>"}`` on a ``point`` or ``spot`` light. Two ways to plug this in, chosen at
import time so that either order of development works:

* If ``backend.lights.point`` reads the ``ies`` field itself (it calls :func:`parse_profile` and
  multiplies its point/spot intensity P/(4π) by the returned :class:`IESEmission` factor, which
  also gives IES on sphere lights as in Cycles), nothing else happens here.
* Otherwise this module wraps the registered ``point``/``spot`` parsers: a node with ``ies`` is
  built as an :class:`IESLight` (a delta emitter), any other node goes to the original parser.
"""
from __future__ import annotations

import importlib

import numpy as np

from ..errors import SceneError
from ..lights import REGISTRY
from ..lights.base import Light, LightSample
from ..mathutil import LUMINANCE
from .lm63 import LM63Error, parse_lm63, read_lm63
from .profile import LUMINOUS_EFFICACY, IESProfile


def spot_attenuation(cos_angle: np.ndarray, cos_half: float, smooth_inv: float) -> np.ndarray:
    """Cycles' spot cone: smoothstep((cos − cos_half) · smooth_inv); smooth_inv = ∞ is a hard edge.

    ``smooth_inv`` = 1 / ((1 − cos_half) · blend) (Cycles ``scene/light.cpp``).
    """
    if not np.isfinite(smooth_inv):
        return (cos_angle > cos_half).astype(np.float64)
    f = np.clip((cos_angle - cos_half) * smooth_inv, 0.0, 1.0)
    return f * f * (3.0 - 2.0 * f)


class IESLight(Light):
    is_delta = True

    def __init__(self, profile: IESProfile, to_world: np.ndarray, power: float,
                 color=(1.0, 1.0, 1.0), spot_size_deg: float | None = None, spot_blend: float = 0.0):
        to_world = np.asarray(to_world, dtype=np.float64)
        self.profile = profile
        self.to_world = to_world
        self.position = to_world[:3, 3].copy()
        self.matrix = to_world[:3, :3].copy()
        self.inv_matrix = np.linalg.inv(self.matrix)
        self.power_w = float(power)
        self.color = np.asarray(color, dtype=np.float64).reshape(3)
        # W/sr per candela per unit colour (Cycles: 4π/177.83 in the table × P/(4π) for the light).
        self.watts_per_candela = self.power_w / LUMINOUS_EFFICACY
        self.spot_size_deg = spot_size_deg
        self.spot_blend = float(spot_blend)
        if spot_size_deg is not None:
            self.cos_half = float(np.cos(np.radians(spot_size_deg) * 0.5))
            denom = (1.0 - self.cos_half) * self.spot_blend
            self.smooth_inv = 1.0 / denom if denom > 0 else np.inf
        else:
            self.cos_half = None
            self.smooth_inv = None

    # ------------------------------------------------------------------ emission
    def to_local(self, w_world: np.ndarray) -> np.ndarray:
        """Unit local directions for world emission directions (n, 3) (zero stays zero)."""
        d = w_world @ self.inv_matrix.T
        n = np.sqrt(np.einsum("ij,ij->i", d, d))
        return d / np.where(n > 0, n, 1.0)[:, None]

    def _factor_local(self, d_local: np.ndarray) -> np.ndarray:
        """Candela × spot attenuation for unit local directions (n, 3)."""
        cd = self.profile.intensity(d_local)
        if self.cos_half is not None:
            cd = cd * spot_attenuation(-d_local[:, 2], self.cos_half, self.smooth_inv)
        return cd

    def intensity(self, w_world: np.ndarray) -> np.ndarray:
        """Radiant intensity (n, 3) [W/sr] emitted along world directions w (from the light)."""
        w_world = np.asarray(w_world, dtype=np.float64).reshape(-1, 3)
        cd = self._factor_local(self.to_local(w_world))
        return (cd * self.watts_per_candela)[:, None] * self.color[None, :]

    def sample(self, p: np.ndarray, u: np.ndarray) -> LightSample:
        d = self.position[None, :] - p
        dist2 = np.einsum("ij,ij->i", d, d)
        ok = dist2 > 0
        dist = np.sqrt(dist2)
        wi = d / np.where(ok, dist, 1.0)[:, None]
        I = self.intensity(-wi)
        value = np.where(ok[:, None], I / np.where(ok, dist2, 1.0)[:, None], 0.0)
        return LightSample(wi, dist, value, np.zeros(p.shape[0]))

    # ------------------------------------------------------------------ power
    def emitted_flux_cd_sr(self) -> float:
        """∫ candela × spot dω over *world* directions [cd·sr = lm]: over local directions with
        the Jacobian |det M| / |M ω_l|³ of ω_l ↦ normalize(M ω_l) (1 for a pure rotation)."""
        weight = None
        if self.cos_half is not None:
            def weight(d_local):
                return spot_attenuation(-d_local[:, 2], self.cos_half, self.smooth_inv)
        return IESEmission(self.profile).mean_factor(self.matrix, weight) * LUMINOUS_EFFICACY

    def power(self) -> float:
        """Emitted power [W] (luminance of the RGB power), integrated from the profile."""
        return float(self.watts_per_candela * self.emitted_flux_cd_sr() * (self.color @ LUMINANCE))

    def radiant_power_rgb(self) -> np.ndarray:
        return self.watts_per_candela * self.emitted_flux_cd_sr() * self.color


# ------------------------------------------------------------------------------------------------
# Scene parsing

def parse_ies(node) -> IESProfile:
    """``{"file": path}`` or ``{"data": "<LM-63 text>"}`` → profile (cached per file and load)."""
    node.require_object()
    has_file, has_data = node.has("file"), node.has("data")
    if has_file == has_data:
        raise node.fail('expected exactly one of "file" (an .ies path) or "data" (LM-63 text)')
    ctx = node.ctx
    if has_file:
        rel = node.string("file")
        path = ctx.resolve(rel)
        key = ("ies-file", str(path))
        if key not in ctx.cache:
            if not path.is_file():
                raise node.fail(f"IES file not found: {path}", "file")
            try:
                ctx.cache[key] = IESProfile(read_lm63(path))
            except LM63Error as exc:
                raise SceneError(ctx.where, node.sub("file"), str(exc)) from None
        profile = ctx.cache[key]
    else:
        text = node.string("data")
        try:
            profile = IESProfile(parse_lm63(text, name="ies.data"))
        except LM63Error as exc:
            raise SceneError(ctx.where, node.sub("data"), exc.detail()) from None
    node.finish()
    for w in profile.source.warnings:
        ctx.warn(node.path, w)
    return profile


class IESEmission:
    """The IES directional factor relative to an isotropic light of the same power.

    A point light of power P has I = P/(4π) W/sr; with IES, Cycles gives P · cd / 177.83 W/sr, so
    the factor is 4π · cd(ω_local) / 177.83 (Cycles bakes 4π/177.83 into its IES table).
    ``__call__`` takes unit local directions (n, 3) and returns (n,).
    """

    def __init__(self, profile: IESProfile):
        self.profile = profile
        self.scale = 4.0 * np.pi / LUMINOUS_EFFICACY

    def __call__(self, local_dirs: np.ndarray) -> np.ndarray:
        return self.scale * self.profile.intensity(local_dirs)

    def mean_factor(self, matrix: np.ndarray | None = None, weight=None) -> float:
        """Mean of the factor (× optional ``weight(local_dirs)``, e.g. a spot cone) over the *world*
        sphere for a light whose ``to_world`` 3×3 part is ``matrix``: the emitted power is
        P × this. Exact quadrature of the interpolated table (not clamped to ≤ 1: a beam that
        concentrates flux has a mean factor of flux/177.83 lm, often well above 1)."""
        M = np.eye(3) if matrix is None else np.asarray(matrix, dtype=np.float64)
        det = abs(float(np.linalg.det(M)))
        orthonormal = np.allclose(M.T @ M, np.eye(3), atol=1e-9)
        if orthonormal and weight is None:
            total = self.profile.flux
        else:
            def w(d_local):
                out = np.ones(d_local.shape[0]) if weight is None else np.asarray(weight(d_local), float)
                if not orthonormal:
                    m = np.linalg.norm(d_local @ M.T, axis=1)
                    out = out * det / np.maximum(m, 1e-300) ** 3
                return out
            # A spot edge is not aligned with table cells: more nodes per cell keep that kink's
            # quadrature error small (this number only steers light selection).
            total = self.profile.integrate(w, nodes=(6, 12))
        return self.scale * total / (4.0 * np.pi)


def parse_profile(node) -> IESEmission:
    """The ``ies`` object of a point/spot light → its directional factor (see IESEmission)."""
    return IESEmission(parse_ies(node))


def ies_light_from_node(node, spot: bool) -> IESLight:
    """A ``point``/``spot`` light node that has an ``ies`` field → :class:`IESLight`."""
    to_world = node.matrix4("to_world")
    color = node.rgb("color", [1.0, 1.0, 1.0])
    power = node.number("power", lo=0.0)
    radius = node.number("radius", 0.0, lo=0.0)
    node.boolean("visible_camera", False)  # a delta light is never seen by camera rays
    node.boolean("soft_falloff", False)    # only matters for radius > 0, which is ignored here
    if radius > 0:
        node.ctx.warn(node.sub("radius"), "IES lights are point emitters in Lamina: radius ignored "
                                          "(soft shadows of a sphere light are not reproduced)")
    size = blend = None
    if spot:
        size = node.number("spot_size", 45.0, lo=0.0, hi=180.0, lo_open=True)
        blend = node.number("spot_blend", 0.15, lo=0.0, hi=1.0)
    profile = parse_ies(node.child("ies"))
    return IESLight(profile, to_world, power, color, size, blend or 0.0)


def _wrap(type_name: str, spot: bool) -> None:
    previous = REGISTRY.get(type_name)
    if getattr(previous, "_ies_wrapper", False):
        return

    def parser(node):
        if node.has("ies"):
            return ies_light_from_node(node, spot)
        if previous is None:
            raise node.fail(f"'{type_name}' lights without an 'ies' profile are not available "
                            "(backend.lights has no parser for them)", "type")
        return previous(node)

    parser._ies_wrapper = True
    parser.__doc__ = f"'{type_name}' light; with an 'ies' field an IES light, else {previous!r}."
    REGISTRY[type_name] = parser


def _install() -> None:
    # Import the plain parsers first so they are registered before being wrapped (later imports of
    # those modules are cached and do not re-register).
    package = __package__.rsplit(".", 1)[0]
    modules = {}
    for mod in ("point", "spot"):
        name = f"{package}.lights.{mod}"
        try:
            modules[mod] = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
    point = modules.get("point")
    if point is not None and hasattr(point, "parse_profile"):
        return  # point/spot lights read "ies" themselves through parse_profile()
    _wrap("point", spot=False)
    _wrap("spot", spot=True)


_install()
