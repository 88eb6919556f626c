"""Rough dielectric (Walter et al. 2007, "Microfacet Models for Refraction through Rough
Surfaces") and the smooth dielectric (α = 0: delta reflection and refraction).

Indices: ``ior`` is the index below the surface (the side the normal points away from),
``ior_above`` the index above; eta = ior / ior_above. Both sides work: wi.z < 0 means the path
arrives from below (inside). For a transmitted direction wo, e = n(wo side) / n(wi side).

Values (eval returns f·|cosθo|, h the half vector oriented to +z):
  reflection    F D G / (4 |cosθi|)                           h ∝ wi + wo
  transmission  (1 − F) D G |wi·h| |wo·h| / (|cosθi| (wi·h + e wo·h)²) × T   h ∝ wi + e wo
where T = ``transmission_color``. That transmission value is the RADIANCE-mode BTDF (it carries
the 1/e² radiance compression across the interface); IMPORTANCE mode multiplies it by e², so
f_importance(wi, wo) = f_radiance(wo, wi) (the adjoint BSDF, Veach 1997 §5.2).

Sampling: visible normals from the side of wi (wi negated into the upper hemisphere when it is
below), then reflect with probability F(wi·m), else refract. Weights: G2/G1(wi) for reflection,
G2/G1(wi) · T / e² (radiance) or · T (importance) for transmission. Smooth lanes: the same choice
with the macro normal, weights 1 and T/e² (or T). Not two-sided: the side decides the indices.
"""
from __future__ import annotations

import numpy as np

from ..kernels.lazy import lazy
from ..kernels.microfacet_codes import ALPHA_MIN, DISTRIBUTION_CODES, MASKING_CODES
from . import register
from .base import ClosedFormBSDF, Material, ShadingContext, lanes, rows1, rows3, taken
from .common import as_param, delta_lanes, parse_microfacet_kind, parse_roughness
from .emission import parse_emission
from .microfacet import GGX, HEIGHT_CORRELATED


_batch = lazy("bsdf.batch")     # compiled on first use (kernels/lazy.py)


class DielectricBSDF(ClosedFormBSDF):
    """Per-lane maths: backend/kernels/bsdf/dielectric.py."""

    transmissive = True

    def __init__(self, n, eta, tint, alpha_u, alpha_v, distribution=GGX,
                 masking=HEIGHT_CORRELATED):
        self.n = n
        # ior / ior_above; () or (n,). A texture may hold 0 (texels are clamped to the range's
        # closed end): keep the index positive so 1/eta stays finite.
        self.eta = np.maximum(np.asarray(eta, dtype=np.float64), 1e-4)
        self.tint = tint                  # (1, 3) or (n, 3) transmission colour
        self.alpha_u, self.alpha_v = alpha_u, alpha_v
        self.distribution, self.masking = distribution, masking
        self.smooth = delta_lanes(alpha_u, alpha_v)
        self.delta_only = bool(np.all(self.smooth))
        self.has_delta = bool(np.any(self.smooth))
        self._args = (rows1(self.eta), rows3(tint),
                      rows1(np.maximum(alpha_u, ALPHA_MIN)), rows1(np.maximum(alpha_v, ALPHA_MIN)),
                      rows1(self.smooth, bool), DISTRIBUTION_CODES[distribution], MASKING_CODES[masking])

    def _eval_pdf(self, wi, wo, mode):
        wi, wo = rows3(wi), rows3(wo)
        f = np.empty((wi.shape[0], 3))
        pdf = np.empty(wi.shape[0])
        _batch.dielectric_eval_pdf(*self._args, int(mode), wi, wo, f, pdf)
        return f, pdf



    def _sample_into(self, wi, rng, mode, out):
        _batch.dielectric_sample(*self._args, int(mode), wi, rng.random((wi.shape[0], 3)), *out)

    def albedo(self):
        # For the denoising AOV: what shows through the glass is tinted by transmission_color.
        return self.tint

    def take(self, idx):
        idx = np.asarray(idx)
        n = taken(idx)
        return DielectricBSDF(n, lanes(self.eta, idx), lanes(self.tint, idx),
                              lanes(self.alpha_u, idx), lanes(self.alpha_v, idx),
                              self.distribution, self.masking)


class DielectricMaterial(Material):
    type_name = "dielectric"
    textured_params = ("ior", "roughness", "roughness_v", "transmission_color")
    two_sided = False

    def __init__(self, ior=1.5, ior_above=1.0, roughness=0.0, roughness_v=None,
                 distribution=GGX, masking=HEIGHT_CORRELATED, transmission_color=1.0,
                 emission=None):
        self.ior = as_param(ior, 1)
        self.ior_above = float(ior_above)
        self.roughness = as_param(roughness, 1)
        self.roughness_v = self.roughness if roughness_v is None else as_param(roughness_v, 1)
        self.distribution, self.masking = distribution, masking
        self.transmission_color = as_param(transmission_color, 3)
        self.emission = emission

    def bind(self, ctx: ShadingContext) -> DielectricBSDF:
        uv = ctx.uv
        return DielectricBSDF(ctx.n, self.ior.bind(uv) / self.ior_above,
                              self.transmission_color.bind(uv), self.roughness.bind(uv),
                              self.roughness_v.bind(uv), self.distribution, self.masking)

    def pack(self, row) -> None:
        from ..kernels import materials as km
        row.kind = km.DIELECTRIC
        row.set(km.D_ETA, self.ior, 1, 1.0 / self.ior_above)
        row.set(km.D_TINT, self.transmission_color, 3)
        row.set(km.D_AU, self.roughness, 1)
        row.set(km.D_AV, self.roughness_v, 1)
        row.microfacet(self.distribution, self.masking)



#: Indices of refraction that real materials span, with margin (germanium's 4.0 is the highest
#: common one; 1/4 that of an inverted interface); outside it a dielectric gets a warning.
PLAUSIBLE_IOR = (0.2, 5.0)


@register("dielectric")
def parse_dielectric(node) -> DielectricMaterial:
    ior = node.param("ior", 1.5, lo=0.0, lo_open=True, color=False)
    ior_above = node.number("ior_above", 1.0, lo=0.0, lo_open=True)
    for key, value in (("ior", float(np.mean(ior.mean()))), ("ior_above", ior_above)):
        if not PLAUSIBLE_IOR[0] <= value <= PLAUSIBLE_IOR[1]:
            # Legal, and rendered as asked, but no real material is near it: at 1e-300 an object
            # vanished without a word (issue 39). Below 1 stays quiet down to 0.2 (an air bubble
            # in water is 0.75).
            node.ctx.warn(node.sub(key), f"index of refraction {value:.3g} is far outside real "
                                         f"materials' ({PLAUSIBLE_IOR[0]:g}–{PLAUSIBLE_IOR[1]:g}; water "
                                         f"1.33, glass 1.5, diamond 2.42): the surface will look "
                                         f"like a mirror or vanish")
    ru, rv = parse_roughness(node, 0.0)
    dist, masking = parse_microfacet_kind(node)
    tint = node.param("transmission_color", [1.0, 1.0, 1.0], channels=3, lo=0.0, color=True)
    return DielectricMaterial(ior, ior_above, ru, rv, dist, masking, tint,
                              emission=parse_emission(node))
