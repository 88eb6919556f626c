"""IES profiles on point and spot lights: the scene-file field and the directional factor.

Units and frame as Cycles ≥ 4.0 (docs/lights.md, IES lights): radiant intensity

    I(ω) [W/sr] = power [W] × candela(ω_local) / 177.83 × colour  (× spot cone for spot lights)

where ω_local = normalize(M⁻¹ ω) for the light's ``to_world`` 3×3 part M (the direction is taken to
object space as Cycles' IES node does with its "incoming" vector) and candela(·) is Cycles'
interpolation of the table (:mod:`backend.ies.profile`).

Scene files: ``"ies": {"file": "lamp.ies"}`` (relative to the scene file) or
``{"data": "<LM-63 text>"}`` on a ``point`` or ``spot`` light. ``backend.lights.point`` reads the
field with :func:`parse_profile` and multiplies its intensity P/(4π) by the returned
:class:`IESEmission` factor — so IES works on sphere lights too, as in Cycles.
"""
from __future__ import annotations


import numpy as np

from ..errors import SceneError
from .lm63 import LM63Error, parse_lm63, read_lm63
from .profile import LUMINOUS_EFFICACY, IESProfile


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
        path = ctx.resolve(rel, node.sub("file"))
        key = ("ies-file", str(path))
        if key not in ctx.cache:
            path = ctx.existing_file(rel, node.sub("file"), "IES file")
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
