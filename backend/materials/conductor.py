"""Rough conductor (microfacet, Cook–Torrance form) and the smooth mirror (α = 0, a delta lobe).

f(wi, wo) = F(wi·h) D(h) G(wi, wo, h) / (4 |cosθi| |cosθo|), h = normalize(wi + wo), with the
exact conductor Fresnel per RGB channel (fresnel.conductor). ``eta``/``k`` are the metal's
complex index; ``eta_above`` is the index of the dielectric the light arrives in (1 = air; a
layered stack sets it to its coating's index), so the Fresnel term uses (eta + i k)/eta_above.

Sampling draws visible normals from wi (microfacet.sample_visible) and reflects; the sample
weight is F · G2/G1(wi) (eval/pdf in closed form). Lanes with α = 0 in both directions are a
perfect mirror: a delta lobe with weight F(cosθi), eval = pdf = 0. Reflection only, two-sided
(wi below the surface is mirrored, see common.upper_side).
"""
from __future__ import annotations

import numpy as np

from ..kernels.lazy import lazy
from ..kernels.microfacet_codes import ALPHA_MIN, DISTRIBUTION_CODES, MASKING_CODES
from ..limits import short as _short
from . import register
from .base import RADIANCE, ClosedFormBSDF, Material, ShadingContext, lanes, rows1, rows3, taken
from .common import as_param, delta_lanes, parse_microfacet_kind, parse_roughness
from .emission import parse_emission
from .metals import METALS, metal_ior
from .microfacet import GGX, HEIGHT_CORRELATED


_batch = lazy("bsdf.batch")     # compiled on first use (kernels/lazy.py)


class ConductorBSDF(ClosedFormBSDF):
    """Per-lane maths: backend/kernels/bsdf/conductor.py."""

    def __init__(self, n, eta, k, tint, alpha_u, alpha_v, distribution=GGX,
                 masking=HEIGHT_CORRELATED):
        self.n = n
        self.eta, self.k = eta, k          # relative to the medium above; (1, 3) or (n, 3)
        self.tint = tint                   # (1, 3) or (n, 3)
        self.alpha_u, self.alpha_v = alpha_u, alpha_v  # () or (n,)
        self.distribution, self.masking = distribution, masking
        self.smooth = delta_lanes(alpha_u, alpha_v)   # () or (n,) bool
        self.delta_only = bool(np.all(self.smooth))
        self.has_delta = bool(np.any(self.smooth))
        self._args = (rows3(eta), rows3(k), rows3(tint),
                      rows1(np.maximum(alpha_u, ALPHA_MIN)), rows1(np.maximum(alpha_v, ALPHA_MIN)),
                      rows1(self.smooth, bool), DISTRIBUTION_CODES[distribution], MASKING_CODES[masking])

    def _eval_pdf(self, wi, wo, mode=RADIANCE):
        wi, wo = rows3(wi), rows3(wo)
        f = np.empty((wi.shape[0], 3))
        pdf = np.empty(wi.shape[0])
        _batch.conductor_eval_pdf(*self._args, wi, wo, f, pdf)
        return f, pdf



    def _sample_into(self, wi, rng, mode, out):
        _batch.conductor_sample(*self._args, wi, rng.random((wi.shape[0], 2)), *out)

    def albedo(self):
        # Normal-incidence reflectance: the metal's colour, what a denoiser wants as albedo.
        a = self._args
        out = np.empty((max(a[0].shape[0], a[1].shape[0], a[2].shape[0]), 3))
        _batch.conductor_albedo(a[0], a[1], a[2], out)
        return out

    def take(self, idx):
        idx = np.asarray(idx)
        n = taken(idx)
        return ConductorBSDF(n, lanes(self.eta, idx), lanes(self.k, idx), lanes(self.tint, idx),
                             lanes(self.alpha_u, idx), lanes(self.alpha_v, idx),
                             self.distribution, self.masking)


class ConductorMaterial(Material):
    type_name = "conductor"
    textured_params = ("eta", "k", "roughness", "roughness_v", "tint")
    two_sided = True

    def __init__(self, eta, k, roughness=0.1, roughness_v=None, distribution=GGX,
                 masking=HEIGHT_CORRELATED, tint=1.0, eta_above=1.0, emission=None):
        self.eta = as_param(eta, 3)
        self.k = as_param(k, 3)
        self.roughness = as_param(roughness, 1)
        self.roughness_v = self.roughness if roughness_v is None else as_param(roughness_v, 1)
        self.distribution, self.masking = distribution, masking
        self.tint = as_param(tint, 3)
        self.eta_above = float(eta_above)
        self.emission = emission

    @classmethod
    def named(cls, metal: str, **kwargs) -> "ConductorMaterial":
        eta, k = metal_ior(metal)
        return cls(eta, k, **kwargs)

    def bind(self, ctx: ShadingContext) -> ConductorBSDF:
        uv = ctx.uv
        inv = 1.0 / self.eta_above
        return ConductorBSDF(ctx.n, self.eta.bind(uv) * inv, self.k.bind(uv) * inv,
                             self.tint.bind(uv), self.roughness.bind(uv), self.roughness_v.bind(uv),
                             self.distribution, self.masking)

    def pack(self, row) -> None:
        from ..kernels import materials as km
        inv = 1.0 / self.eta_above
        row.kind = km.CONDUCTOR
        row.set(km.ETA, self.eta, 3, inv)
        row.set(km.K, self.k, 3, inv)
        row.set(km.TINT, self.tint, 3)
        row.set(km.AU, self.roughness, 1)
        row.set(km.AV, self.roughness_v, 1)
        row.microfacet(self.distribution, self.masking)



@register("conductor")
def parse_conductor(node) -> ConductorMaterial:
    has_eta, has_k = node.has("eta"), node.has("k")
    if node.has("metal") and (has_eta or has_k):
        raise node.fail("give either a named metal or eta and k, not both", "metal")
    if has_eta != has_k:
        raise node.fail("eta and k must be given together", "k" if has_eta else "eta")
    if has_eta:
        eta = node.param("eta", channels=3, lo=0.0, color=False)
        k = node.param("k", channels=3, lo=0.0, color=False)
        node.ignore("metal")
    else:
        name = node.string("metal", "Cu")
        if name not in METALS:
            raise node.fail(f"unknown metal {_short(name)!r} (known: {', '.join(sorted(METALS))})", "metal")
        eta, k = metal_ior(name)
        node.ignore("eta", "k")
    ru, rv = parse_roughness(node, 0.1)
    dist, masking = parse_microfacet_kind(node)
    tint = node.param("tint", [1.0, 1.0, 1.0], channels=3, lo=0.0, color=True)
    eta_above = node.number("eta_above", 1.0, lo=0.0, lo_open=True)
    return ConductorMaterial(eta, k, ru, rv, dist, masking, tint, eta_above,
                             emission=parse_emission(node))
