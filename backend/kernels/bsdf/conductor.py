"""Rough conductor (Cook–Torrance microfacet form) and the smooth mirror (α = 0: a delta lobe).

f(wi, wo) = F(wi·h) D(h) G(wi, wo, h)/(4 |cos θi| |cos θo|), h = normalize(wi + wo), with the
exact conductor Fresnel per RGB channel; ``eta``/``k`` are relative to the medium above. Sampling
draws visible normals from wi and reflects: weight F·G2/G1(wi). Reflection only, two-sided (wi
below the surface is mirrored). ``smooth`` lanes (αu = αv = 0 before clamping) are a perfect
mirror with weight F(cos θi) and eval = pdf = 0.
"""
from __future__ import annotations

from .. import microfacet as mf
from ..fresnel import conductor_rgb
from ..jit import inlined, kernel
from ..vec import normalize

ZERO3 = (0.0, 0.0, 0.0)


@kernel
def _upper(w, s):
    return (w[0], w[1], w[2] * s)


@kernel
def eval_pdf(eta, k, tint, au, av, smooth, dist, masking, wi, wo):
    if smooth:
        return ZERO3, 0.0
    s = -1.0 if wi[2] < 0.0 else 1.0
    wi_u = _upper(wi, s)
    wo_u = _upper(wo, s)
    if not (wi_u[2] > 0.0 and wo_u[2] > 0.0):
        return ZERO3, 0.0
    h = normalize((wi_u[0] + wo_u[0], wi_u[1] + wo_u[1], wi_u[2] + wo_u[2]))
    d = mf.D(dist, au, av, h)
    inv = 1.0 / (4.0 * wi_u[2])
    val = d * mf.G(dist, masking, au, av, wi_u, wo_u, h) * inv
    F = conductor_rgb(wi_u[0] * h[0] + wi_u[1] * h[1] + wi_u[2] * h[2], eta, k)
    # Visible-normal density / (4 |wo·h|); wi·h = wo·h for a reflection, so it cancels.
    pdf = mf.G1(dist, au, av, wi_u, h) * d * inv
    return (F[0] * tint[0] * val, F[1] * tint[1] * val, F[2] * tint[2] * val), pdf


@kernel
def sample(eta, k, tint, au, av, smooth, dist, masking, wi, u0, u1):
    s = -1.0 if wi[2] < 0.0 else 1.0
    wi_u = _upper(wi, s)
    if not wi_u[2] > 0.0:
        return _upper((0.0, 0.0, 1.0), s), ZERO3, 0.0, False
    if smooth:
        F = conductor_rgb(wi_u[2], eta, k)
        wo = (-wi_u[0], -wi_u[1], wi_u[2])
        return _upper(wo, s), (F[0] * tint[0], F[1] * tint[1], F[2] * tint[2]), 0.0, True
    m = mf.sample_visible(dist, au, av, wi_u, u0, u1)
    cos_im = wi_u[0] * m[0] + wi_u[1] * m[1] + wi_u[2] * m[2]
    wo = (2.0 * cos_im * m[0] - wi_u[0], 2.0 * cos_im * m[1] - wi_u[1], 2.0 * cos_im * m[2] - wi_u[2])
    if not wo[2] > 0.0:
        return _upper(wo, s), ZERO3, 0.0, False
    g1 = mf.G1(dist, au, av, wi_u, m)
    if not g1 > 0.0:
        return _upper(wo, s), ZERO3, 0.0, False
    ratio = mf.G(dist, masking, au, av, wi_u, wo, m) / g1
    F = conductor_rgb(cos_im, eta, k)
    pdf = g1 * mf.D(dist, au, av, m) / (4.0 * wi_u[2])
    return _upper(wo, s), (F[0] * tint[0] * ratio, F[1] * tint[1] * ratio, F[2] * tint[2] * ratio), pdf, False


@kernel
def albedo(eta, k, tint):
    """Normal-incidence reflectance: the metal's colour, what a denoiser wants as albedo."""
    F = conductor_rgb(1.0, eta, k)
    return (F[0] * tint[0], F[1] * tint[1], F[2] * tint[2])


# ----------------------------------------------------------------------------- binding
# The kind's slots in a material row (kernels/materials.py ``MaterialTable.values``: its Python
# material packs them) and its lane parameters: the 12-tuple every kind binds to (one Numba type
# for all, kernels/materials.py ``bind``), written and read here only.
ETA, K, TINT, AU, AV = 3, 6, 9, 12, 13     # relative eta (RGB), k (RGB), tint (RGB), α


@inlined
def params(eta, k, tint, au, av):
    smooth = 1.0 if (au <= 0.0 and av <= 0.0) else 0.0
    return (eta[0], eta[1], eta[2], k[0], k[1], k[2], tint[0], tint[1], tint[2],
            max(au, mf.ALPHA_MIN), max(av, mf.ALPHA_MIN), smooth)


@inlined
def eval_pdf_p(p, dist, masking, wi, wo):
    return eval_pdf((p[0], p[1], p[2]), (p[3], p[4], p[5]), (p[6], p[7], p[8]), p[9], p[10], p[11] > 0.0,
                    dist, masking, wi, wo)


@inlined
def sample_p(p, dist, masking, wi, u0, u1):
    return sample((p[0], p[1], p[2]), (p[3], p[4], p[5]), (p[6], p[7], p[8]), p[9], p[10], p[11] > 0.0,
                  dist, masking, wi, u0, u1)


@inlined
def albedo_p(p):
    return albedo((p[0], p[1], p[2]), (p[3], p[4], p[5]), (p[6], p[7], p[8]))


@inlined
def delta_only_p(p):
    return p[11] > 0.0
