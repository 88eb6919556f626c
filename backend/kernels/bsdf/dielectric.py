"""Rough dielectric (Walter et al. 2007) and the smooth dielectric (α = 0: delta reflection and
refraction).

``eta`` = ior below / ior above (clamped to ≥ 1e-4 by the caller's table). Both sides work:
wi.z < 0 arrives from below. For a transmitted wo, e = n(wo side)/n(wi side). eval (h the half
vector oriented to +z):
  reflection    F D G / (4 |cos θi|)                                   h ∝ wi + wo
  transmission  (1 − F) D G |wi·h| |wo·h| / (|cos θi| (wi·h + e wo·h)²) × T    h ∝ wi + e wo
with T = the transmission colour. That is the RADIANCE-mode BTDF (it carries the 1/e² radiance
compression); IMPORTANCE mode multiplies it by e², so f_importance(wi, wo) = f_radiance(wo, wi)
(Veach 1997 §5.2). Sampling: visible normals from wi's side, reflect with probability F(wi·m),
else refract; weights G2/G1(wi), times T/e² (radiance) or T (importance) for transmission.
Not two-sided: the side decides the indices.
"""
from __future__ import annotations

import math

from .. import microfacet as mf
from ..fresnel import dielectric as fresnel
from . import RADIANCE
from ..jit import inlined, kernel

ZERO3 = (0.0, 0.0, 0.0)


@kernel
def _div(a, b):
    return a / b if b != 0.0 else 0.0


@kernel
def eval_pdf(eta, tint, au, av, smooth, dist, masking, mode, wi, wo):
    if smooth:
        return ZERO3, 0.0
    ci = wi[2]
    co = wo[2]
    reflect = ci * co > 0.0
    transmit = ci * co < 0.0
    if not (reflect or transmit):
        return ZERO3, 0.0
    e = eta if ci > 0.0 else 1.0 / eta
    if reflect:
        hx, hy, hz = wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]
    else:
        hx, hy, hz = wi[0] + e * wo[0], wi[1] + e * wo[1], wi[2] + e * wo[2]
    hn = math.sqrt(hx * hx + hy * hy + hz * hz)
    if hn > 0.0:
        hx, hy, hz = hx / hn, hy / hn, hz / hn
    if hz < 0.0:
        hx, hy, hz = -hx, -hy, -hz
    if not hz > 0.0:
        return ZERO3, 0.0
    h = (hx, hy, hz)
    cih = wi[0] * hx + wi[1] * hy + wi[2] * hz
    coh = wo[0] * hx + wo[1] * hy + wo[2] * hz
    # Transmission needs wi and wo on opposite sides of the microfacet, reflection the same.
    if reflect and not cih * coh > 0.0:
        return ZERO3, 0.0
    if transmit and not cih * coh < 0.0:
        return ZERO3, 0.0
    F = fresnel(cih, eta)[0]
    DG = mf.D(dist, au, av, h) * mf.G(dist, masking, au, av, wi, wo, h)
    aci = abs(ci)
    side = -1.0 if ci < 0.0 else 1.0
    p_h = mf.pdf_visible(dist, au, av, (wi[0] * side, wi[1] * side, wi[2] * side), h)
    if reflect:
        fr = _div(F * DG, 4.0 * aci)
        return (fr, fr, fr), _div(F * p_h, 4.0 * abs(coh))
    den = cih + e * coh
    ft = _div((1.0 - F) * DG * abs(cih * coh), aci * den * den)
    if mode != RADIANCE:
        ft = ft * e * e
    pt = _div((1.0 - F) * p_h * e * e * abs(coh), den * den)
    return (ft * tint[0], ft * tint[1], ft * tint[2]), pt


@kernel
def sample(eta, tint, au, av, smooth, dist, masking, mode, wi, u0, u1, u2):
    ci = wi[2]
    if ci == 0.0:
        return (0.0, 0.0, 1.0), ZERO3, 0.0, False
    side = -1.0 if ci < 0.0 else 1.0
    if smooth:
        F, cos_t, e = fresnel(ci, eta)
        if u2 < F:
            return (-wi[0], -wi[1], wi[2]), (1.0, 1.0, 1.0), 0.0, True
        ts = 1.0 if mode != RADIANCE else 1.0 / (e * e)
        return (-wi[0] / e, -wi[1] / e, cos_t), (tint[0] * ts, tint[1] * ts, tint[2] * ts), 0.0, True
    ws = (wi[0] * side, wi[1] * side, wi[2] * side)
    m = mf.sample_visible(dist, au, av, ws, u0, u1)
    cim = wi[0] * m[0] + wi[1] * m[1] + wi[2] * m[2]
    F, cos_t, e = fresnel(cim, eta)
    choose_r = u2 < F
    if choose_r:
        wo = (2.0 * cim * m[0] - wi[0], 2.0 * cim * m[1] - wi[1], 2.0 * cim * m[2] - wi[2])
        ok = cim * ci > 0.0 and wo[2] * ci > 0.0
    else:
        a = cim / e + cos_t
        wo = (-wi[0] / e + a * m[0], -wi[1] / e + a * m[1], -wi[2] / e + a * m[2])
        ok = cim * ci > 0.0 and wo[2] * ci < 0.0 and cos_t != 0.0
    if not ok:
        return wo, ZERO3, 0.0, False
    com = wo[0] * m[0] + wo[1] * m[1] + wo[2] * m[2]
    g1 = mf.G1(dist, au, av, ws, m)
    ratio = _div(mf.G(dist, masking, au, av, wi, wo, m), g1)
    p_h = mf.pdf_visible(dist, au, av, ws, m)
    if choose_r:
        return wo, (ratio, ratio, ratio), _div(F * p_h, 4.0 * abs(com)), False
    den = cim + e * com
    pt = _div((1.0 - F) * p_h * e * e * abs(com), den * den)
    ts = 1.0 if mode != RADIANCE else _div(1.0, e * e)
    w = ratio * ts
    return wo, (tint[0] * w, tint[1] * w, tint[2] * w), pt, False


# ----------------------------------------------------------------------------- binding
# The kind's slots in a material row (kernels/materials.py ``MaterialTable.values``: its Python
# material packs them) and its lane parameters: the 12-tuple every kind binds to (one Numba type
# for all, kernels/materials.py ``bind``), written and read here only.
ETA, TINT, AU, AV = 3, 4, 7, 8      # relative eta, transmission colour (RGB), α


@inlined
def params(eta, tint, au, av):
    # A texture may hold 0 (texels are clamped to the range's closed end): keep the index
    # positive so 1/eta stays finite.
    eta = max(eta, 1e-4)
    smooth = 1.0 if (au <= 0.0 and av <= 0.0) else 0.0
    return (eta, tint[0], tint[1], tint[2], max(au, mf.ALPHA_MIN), max(av, mf.ALPHA_MIN), smooth,
            0.0, 0.0, 0.0, 0.0, 0.0)


@inlined
def eval_pdf_p(p, dist, masking, mode, wi, wo):
    return eval_pdf(p[0], (p[1], p[2], p[3]), p[4], p[5], p[6] > 0.0, dist, masking, mode, wi, wo)


@inlined
def sample_p(p, dist, masking, mode, wi, u0, u1, u2):
    return sample(p[0], (p[1], p[2], p[3]), p[4], p[5], p[6] > 0.0, dist, masking, mode, wi, u0, u1, u2)


@inlined
def albedo_p(p):
    return (p[1], p[2], p[3])


@inlined
def delta_only_p(p):
    return p[6] > 0.0


@inlined
def smooth_reflectance(eta, smooth, wi):
    """The Fresnel reflectance F of a smooth interface seen from above (wi.z > 0), 0 where it is
    rough or seen from below: what a sampler that picks the delta mirror by a random number
    returns there on average (this one: probability F, weight 1; the coated kinds' top_or_body:
    probability w_s, weight F/w_s)."""
    if smooth and wi[2] > 0.0:
        return fresnel(wi[2], eta)[0]
    return 0.0


@inlined
def smooth_reflectance_p(p, wi):
    return smooth_reflectance(p[0], p[6] > 0.0, wi)
