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

from . import register
from .base import BSDF, RADIANCE, BSDFSample, Material, ShadingContext, lanes
from .common import (any_textured, as_param, col, delta_lanes, dot, normalize,
                     parse_microfacet_kind, parse_roughness)
from .emission import parse_emission
from .fresnel import dielectric as fresnel_dielectric
from .microfacet import GGX, HEIGHT_CORRELATED, Microfacet


def _div(num, den):
    ok = den != 0
    return np.where(ok, num / np.where(ok, den, 1.0), 0.0)


class DielectricBSDF(BSDF):
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
        self.mf = Microfacet(distribution, alpha_u, alpha_v, masking)
        self.smooth = delta_lanes(alpha_u, alpha_v)
        self.delta_only = bool(np.all(self.smooth))
        self.has_delta = bool(np.any(self.smooth))

    # ------------------------------------------------------------------ geometry
    def _half(self, wi, wo):
        """(h oriented to +z, reflect mask, transmit mask, e = n_wo / n_wi for transmission)."""
        ci, co = wi[:, 2], wo[:, 2]
        reflect = ci * co > 0
        transmit = ci * co < 0
        e = np.where(ci > 0, self.eta, 1.0 / self.eta)
        h = np.where(reflect[:, None], wi + wo, wi + e[:, None] * wo)
        h = normalize(h)
        h = h * np.where(h[:, 2] < 0, -1.0, 1.0)[:, None]
        ok = h[:, 2] > 0
        return h, reflect & ok, transmit & ok, e

    def _parts(self, wi, wo):
        h, refl, trans, e = self._half(wi, wo)
        cih, coh = dot(wi, h), dot(wo, h)
        F = fresnel_dielectric(cih, self.eta)[0]
        # Transmission needs wi and wo on opposite sides of the microfacet, reflection the same.
        refl &= cih * coh > 0
        trans &= cih * coh < 0
        rough = ~np.broadcast_to(self.smooth, (wi.shape[0],))
        refl &= rough
        trans &= rough
        return h, refl, trans, e, cih, coh, F

    # ------------------------------------------------------------------ queries
    def eval(self, wi, wo, rng=None, mode=RADIANCE):
        n = wi.shape[0]
        if self.delta_only:
            return np.zeros((n, 3))
        h, refl, trans, e, cih, coh, F = self._parts(wi, wo)
        DG = self.mf.D(h) * self.mf.G(wi, wo, h)
        aci = np.abs(wi[:, 2])
        fr = _div(F * DG, 4.0 * aci)
        ft = _div((1.0 - F) * DG * np.abs(cih * coh), aci * (cih + e * coh) ** 2)
        if mode != RADIANCE:
            ft = ft * e * e
        out = np.where(refl[:, None], fr[:, None], 0.0)
        return out + np.where(trans[:, None], ft[:, None] * self.tint, 0.0)

    def pdf(self, wi, wo, rng=None, mode=RADIANCE):
        n = wi.shape[0]
        if self.delta_only:
            return np.zeros(n)
        h, refl, trans, e, cih, coh, F = self._parts(wi, wo)
        side = np.where(wi[:, 2] < 0, -1.0, 1.0)[:, None]
        p_h = self.mf.pdf_visible(wi * side, h)
        pr = _div(F * p_h, 4.0 * np.abs(coh))
        pt = _div((1.0 - F) * p_h * e * e * np.abs(coh), (cih + e * coh) ** 2)
        return np.where(refl, pr, 0.0) + np.where(trans, pt, 0.0)

    def sample(self, wi, rng, mode=RADIANCE):
        n = wi.shape[0]
        u = rng.random((n, 3))
        ci = wi[:, 2]
        front_or_back = ci != 0
        side = np.where(ci < 0, -1.0, 1.0)
        wo = np.zeros((n, 3))
        weight = np.zeros((n, 3))
        pdf = np.zeros(n)
        delta = np.zeros(n, dtype=bool)
        if not self.delta_only:
            ws = wi * side[:, None]
            m = self.mf.sample_visible(ws, u[:, :2])
            cim = dot(wi, m)
            F, cos_t, e = fresnel_dielectric(cim, self.eta)
            choose_r = u[:, 2] < F
            wo_r = 2.0 * cim[:, None] * m - wi
            wo_t = -wi / e[:, None] + (cim / e + cos_t)[:, None] * m
            wo = np.where(choose_r[:, None], wo_r, wo_t)
            com = dot(wo, m)
            ok = front_or_back & (cim * ci > 0) & np.where(choose_r, wo[:, 2] * ci > 0,
                                                           (wo[:, 2] * ci < 0) & (cos_t != 0))
            g1 = self.mf.G1(ws, m)
            ratio = _div(self.mf.G(wi, wo, m), g1)
            p_h = self.mf.pdf_visible(ws, m)
            pr = _div(F * p_h, 4.0 * np.abs(com))
            pt = _div((1.0 - F) * p_h * e * e * np.abs(com), (cim + e * com) ** 2)
            tscale = np.ones(n) if mode != RADIANCE else _div(np.ones(n), e * e)
            w_t = self.tint * col(ratio * tscale)
            weight = np.where(choose_r[:, None], ratio[:, None], w_t)
            weight = np.where(ok[:, None], weight, 0.0)
            pdf = np.where(ok, np.where(choose_r, pr, pt), 0.0)
        if self.has_delta:
            sm = np.broadcast_to(self.smooth, (n,)) & front_or_back
            F, cos_t, e = fresnel_dielectric(ci, self.eta)
            choose_r = u[:, 2] < F
            wo_r = wi * np.array([-1.0, -1.0, 1.0])
            wo_t = np.stack([-wi[:, 0] / e, -wi[:, 1] / e, cos_t], axis=1)
            wo_d = np.where(choose_r[:, None], wo_r, wo_t)
            tscale = np.ones(n) if mode != RADIANCE else 1.0 / (e * e)
            w_d = np.where(choose_r[:, None], 1.0, self.tint * col(tscale))
            wo = np.where(sm[:, None], wo_d, wo)
            weight = np.where(sm[:, None], w_d, weight)
            pdf = np.where(sm, 0.0, pdf)
            delta = sm
        return BSDFSample(wo, weight, pdf, delta)

    def albedo(self):
        # For the denoising AOV: what shows through the glass is tinted by transmission_color.
        return self.tint

    def take(self, idx):
        idx = np.asarray(idx)
        n = int(idx.sum()) if idx.dtype == bool else idx.size
        return DielectricBSDF(n, lanes(self.eta, idx), lanes(self.tint, idx),
                              lanes(self.alpha_u, idx), lanes(self.alpha_v, idx),
                              self.distribution, self.masking)


class DielectricMaterial(Material):
    type_name = "dielectric"
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

    @property
    def uses_textures(self) -> bool:
        return any_textured(self.ior, self.roughness, self.roughness_v, self.transmission_color)


@register("dielectric")
def parse_dielectric(node) -> DielectricMaterial:
    ior = node.param("ior", 1.5, lo=0.0, lo_open=True, color=False)
    ior_above = node.number("ior_above", 1.0, lo=0.0, lo_open=True)
    ru, rv = parse_roughness(node, 0.0)
    dist, masking = parse_microfacet_kind(node)
    tint = node.param("transmission_color", [1.0, 1.0, 1.0], channels=3, lo=0.0, color=True)
    return DielectricMaterial(ior, ior_above, ru, rv, dist, masking, tint,
                              emission=parse_emission(node))
