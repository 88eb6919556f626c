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

from . import register
from .base import BSDF, BSDFSample, Material, ShadingContext, lanes
from ..mathutil import scale_rows
from .common import (any_textured, as_param, delta_lanes, dot, mirror_z, normalize,
                     parse_microfacet_kind, parse_roughness, upper_side)
from .emission import parse_emission
from .fresnel import conductor as fresnel_conductor
from .metals import METALS, metal_ior
from .microfacet import GGX, HEIGHT_CORRELATED, Microfacet


class ConductorBSDF(BSDF):
    def __init__(self, n, eta, k, tint, alpha_u, alpha_v, distribution=GGX,
                 masking=HEIGHT_CORRELATED):
        self.n = n
        self.eta, self.k = eta, k          # relative to the medium above; (1, 3) or (n, 3)
        self.tint = tint                   # (1, 3) or (n, 3)
        self.alpha_u, self.alpha_v = alpha_u, alpha_v  # () or (n,)
        self.distribution, self.masking = distribution, masking
        self.mf = Microfacet(distribution, alpha_u, alpha_v, masking)
        self.smooth = delta_lanes(alpha_u, alpha_v)   # () or (n,) bool
        self.delta_only = bool(np.all(self.smooth))
        self.has_delta = bool(np.any(self.smooth))

    def _fresnel(self, cos_i):
        eta, k, tint = (np.asarray(x, dtype=np.float64) for x in (self.eta, self.k, self.tint))
        if not all(x.size == 3 for x in (eta, k, tint)):   # textured: per-lane (n, 3) parameters
            return fresnel_conductor(cos_i[:, None], eta, k) * tint
        # Constant metal: one channel at a time on 1-D arrays. The same arithmetic through
        # (n, 1) × (1, 3) broadcasting runs numpy's loops 3 elements at a time (5x slower).
        eta, k, tint = eta.reshape(3), k.reshape(3), tint.reshape(3)
        out = np.empty((cos_i.shape[0], 3))
        for ch in range(3):
            out[:, ch] = fresnel_conductor(cos_i, eta[ch], k[ch]) * tint[ch]
        return out

    def eval(self, wi, wo, rng=None, mode=0):
        n = wi.shape[0]
        if self.delta_only:
            return np.zeros((n, 3))
        s = upper_side(wi)
        wi_u, wo_u = mirror_z(wi, s), mirror_z(wo, s)
        ok = (wi_u[:, 2] > 0) & (wo_u[:, 2] > 0) & ~self.smooth
        h = normalize(wi_u + wo_u)
        val = self.mf.D(h) * self.mf.G(wi_u, wo_u, h) / np.where(ok, 4.0 * wi_u[:, 2], 1.0)
        return np.where(ok[:, None], self._fresnel(dot(wi_u, h)) * val[:, None], 0.0)

    def pdf(self, wi, wo, rng=None, mode=0):
        n = wi.shape[0]
        if self.delta_only:
            return np.zeros(n)
        s = upper_side(wi)
        wi_u, wo_u = mirror_z(wi, s), mirror_z(wo, s)
        ok = (wi_u[:, 2] > 0) & (wo_u[:, 2] > 0) & ~self.smooth
        h = normalize(wi_u + wo_u)
        # Visible-normal density / (4 |wo·h|); wi·h = wo·h for a reflection, so it cancels.
        p = self.mf.G1(wi_u, h) * self.mf.D(h) / np.where(ok, 4.0 * wi_u[:, 2], 1.0)
        return np.where(ok, p, 0.0)

    def sample(self, wi, rng, mode=0):
        n = wi.shape[0]
        s = upper_side(wi)
        wi_u = mirror_z(wi, s)
        u = rng.random((n, 2))
        front = wi_u[:, 2] > 0
        wo_u = np.zeros((n, 3))
        weight = np.zeros((n, 3))
        pdf = np.zeros(n)
        delta = np.zeros(n, dtype=bool)
        if not self.delta_only:
            m = self.mf.sample_visible(wi_u, u)
            cos_im = dot(wi_u, m)
            wo_r = 2.0 * cos_im[:, None] * m - wi_u
            ok = front & (wo_r[:, 2] > 0) & ~self.smooth
            g1 = self.mf.G1(wi_u, m)
            g1_safe = np.where(g1 > 0, g1, 1.0)
            ratio = np.where(ok & (g1 > 0), self.mf.G(wi_u, wo_r, m) / g1_safe, 0.0)
            weight = scale_rows(ratio, self._fresnel(cos_im))
            pdf = np.where(ok, g1 * self.mf.D(m) / np.where(front, 4.0 * wi_u[:, 2], 1.0), 0.0)
            wo_u = wo_r
        if self.has_delta:
            sm = np.broadcast_to(self.smooth, (n,)) & front
            mirror = wi_u * np.array([-1.0, -1.0, 1.0])
            wo_u = np.where(sm[:, None], mirror, wo_u)
            weight = np.where(sm[:, None], self._fresnel(wi_u[:, 2]), weight)
            pdf = np.where(sm, 0.0, pdf)
            delta = sm
        weight = np.where(front[:, None], weight, 0.0)
        return BSDFSample(mirror_z(wo_u, s), weight, pdf, delta)

    def albedo(self):
        # Normal-incidence reflectance: the metal's colour, what a denoiser wants as albedo.
        return fresnel_conductor(np.ones((1, 1)), self.eta, self.k) * self.tint

    def take(self, idx):
        idx = np.asarray(idx)
        n = int(idx.sum()) if idx.dtype == bool else idx.size
        return ConductorBSDF(n, lanes(self.eta, idx), lanes(self.k, idx), lanes(self.tint, idx),
                             lanes(self.alpha_u, idx), lanes(self.alpha_v, idx),
                             self.distribution, self.masking)


class ConductorMaterial(Material):
    type_name = "conductor"
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

    @property
    def uses_textures(self) -> bool:
        return any_textured(self.eta, self.k, self.roughness, self.roughness_v, self.tint)


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
            raise node.fail(f"unknown metal {name!r} (known: {', '.join(sorted(METALS))})", "metal")
        eta, k = metal_ior(name)
        node.ignore("eta", "k")
    ru, rv = parse_roughness(node, 0.1)
    dist, masking = parse_microfacet_kind(node)
    tint = node.param("tint", [1.0, 1.0, 1.0], channels=3, lo=0.0, color=True)
    eta_above = node.number("eta_above", 1.0, lo=0.0, lo_open=True)
    return ConductorMaterial(eta, k, ru, rv, dist, masking, tint, eta_above,
                             emission=parse_emission(node))
