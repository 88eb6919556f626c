"""The interfaces of a layer stack as the walk and the estimators need them, per lane.

The walk and the connections need, for every interface vertex, the sample together with the
forward and reverse sampling densities, and for every connection the value together with both
densities: ``sample`` and ``evaluate`` compute them in one pass, sharing the half vector, D,
the masking terms and Fresnel. Parameters and maths are the standard BSDFs'
(kernels/bsdf/*.py; tests compare them), in IMPORTANCE transport (the physical flow wi → wo),
values f·|cos θo|, densities per unit solid angle; delta samples carry the placeholder densities 1
(see estimators.py).

One deliberate difference from the standard BSDFs: a Beckmann interface is sampled inside the
stack with m ∝ D(m) cos θm (closed form) instead of visible normals (a Newton iteration on erfc);
the densities reported are this sampler's, so the walk stays exact. GGX uses visible normals.

Bound interface block (``B[o + …]``, written by kernels/layered/table.py's bind_iface): kind (DIFFUSE, CONDUCTOR,
DIELECTRIC of kernels/materials.py, or NULL: an index-matched pass-through with a tint), the
microfacet codes, the 12 material parameters of ``kernels.materials.bind``, and an optional
shading normal (a per-interface normal map: the interface works in the frame (s, t, n), and a
walk arriving along −w multiplies in ``arrival(w)`` = |⟨n, w⟩|/|w_z|, so that every segment carries
Guo's symmetric term τ·|⟨n_a, d⟩|·|⟨n_b, d⟩|/|cos d|; directions on different sides of the shading
and the geometric normal are rejected, as in Guo et al.'s code).

Masking terms (``term``): the rational G1 for separable Beckmann, else Smith Λ; ``g2`` combines
two of them, so the connections compute each direction's term once (``evaluate``'s ti, to).
"""
from __future__ import annotations

import math

from .. import microfacet as mf
from ..fresnel import conductor as fresnel_conductor
from ..fresnel import dielectric as fresnel_dielectric
from ..jit import kernel
from ..materials import CONDUCTOR, DIELECTRIC, DIFFUSE
from ..turns import cos_sin_turns

NULL = 5
# Block layout (offsets from o)
IF_KIND, IF_DIST, IF_MASK, IF_P, IF_FRAMED, IF_N, IF_S, IF_T, IF_DELTA, IF_TRANS = \
    0, 1, 2, 3, 15, 16, 19, 22, 25, 26
STRIDE = 28
from ..consts import INV_PI
NAN = math.nan


@kernel(error_model="numpy")
def is_delta(B, o):
    return B[o + IF_DELTA] > 0.0


@kernel(error_model="numpy")
def _local(B, o, w):
    s, t, n = o + IF_S, o + IF_T, o + IF_N
    return (w[0] * B[s] + w[1] * B[s + 1] + w[2] * B[s + 2],
            w[0] * B[t] + w[1] * B[t + 1] + w[2] * B[t + 2],
            w[0] * B[n] + w[1] * B[n + 1] + w[2] * B[n + 2])


@kernel(error_model="numpy")
def _world(B, o, w):
    s, t, n = o + IF_S, o + IF_T, o + IF_N
    return (w[0] * B[s] + w[1] * B[t] + w[2] * B[n],
            w[0] * B[s + 1] + w[1] * B[t + 1] + w[2] * B[n + 1],
            w[0] * B[s + 2] + w[1] * B[t + 2] + w[2] * B[n + 2])


@kernel(error_model="numpy")
def arrival(B, o, w):
    """|⟨n, w⟩|/|w_z| for a normal-mapped interface reached along −w (0 across the normals), 1
    without a normal map."""
    if B[o + IF_FRAMED] <= 0.0:
        return 1.0
    c = w[0] * B[o + IF_N] + w[1] * B[o + IF_N + 1] + w[2] * B[o + IF_N + 2]
    if not c * w[2] > 0.0:
        return 0.0
    return abs(c) / abs(w[2])


@kernel(error_model="numpy")
def frame_of_normal(n):
    """(s, t) of a shading normal: the tangent x projected off n (y where x is parallel to n)."""
    x = (1.0 - n[0] * n[0], -n[0] * n[1], -n[0] * n[2])
    if math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) <= 1e-6:
        x = (-n[1] * n[0], 1.0 - n[1] * n[1], -n[1] * n[2])
    ln = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    s = (x[0] / ln, x[1] / ln, x[2] / ln) if ln > 0.0 else (1.0, 0.0, 0.0)
    t = (n[1] * s[2] - n[2] * s[1], n[2] * s[0] - n[0] * s[2], n[0] * s[1] - n[1] * s[0])
    return s, t


# ----------------------------------------------------------------------------- microfacets
@kernel(error_model="numpy")
def _term(dist, masking, au, av, w):
    if masking == mf.SEPARABLE and dist == mf.BECKMANN:
        a = 1.0 / math.sqrt(max(mf.alpha2_tan2(au, av, w), 1e-200))
        if a < 1.6:
            return (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
        return 1.0
    return mf.smith_lambda(dist, au, av, w)


@kernel(error_model="numpy")
def _g2(dist, masking, ti, to, chi):
    if not chi:
        return 0.0
    if masking == mf.SEPARABLE:
        if dist == mf.BECKMANN:
            return ti * to
        return 1.0 / ((1.0 + ti) * (1.0 + to))
    return 1.0 / (1.0 + ti + to)


@kernel(error_model="numpy")
def _normal(dist, au, av, ws, u0, u1):
    if dist == mf.BECKMANN:
        return mf.sample_ndf(dist, au, av, u0, u1)
    return mf.sample_visible(dist, au, av, ws, u0, u1)


@kernel(error_model="numpy")
def alphas(B, o):
    kind = B[o + IF_KIND]
    if kind == CONDUCTOR:
        return B[o + IF_P + 9], B[o + IF_P + 10]
    return B[o + IF_P + 4], B[o + IF_P + 5]


@kernel(error_model="numpy")
def term(B, o, w):
    """The masking term of direction w at a rough interface (in its shading frame); 0 else."""
    kind = B[o + IF_KIND]
    if not (kind == CONDUCTOR or kind == DIELECTRIC) or B[o + IF_DELTA] > 0.0:
        return 0.0
    if B[o + IF_FRAMED] > 0.0:
        w = _local(B, o, w)
    au, av = alphas(B, o)
    return _term(int(B[o + IF_DIST]), int(B[o + IF_MASK]), au, av, w)


# ----------------------------------------------------------------------------- per kind
@kernel(error_model="numpy")
def _conductor_sample(B, o, wi, u0, u1, dens):
    p = o + IF_P
    s = -1.0 if wi[2] < 0.0 else 1.0
    ci = wi[2] * s
    zero = (0.0, 0.0, 0.0)
    if not ci > 0.0:
        return (0.0, 0.0, s), zero, 0.0, 0.0, False
    eta = (B[p], B[p + 1], B[p + 2])
    k = (B[p + 3], B[p + 4], B[p + 5])
    if B[p + 11] > 0.0:      # smooth: a mirror
        w = (fresnel_conductor(ci, eta[0], k[0]) * B[p + 6], fresnel_conductor(ci, eta[1], k[1]) * B[p + 7],
             fresnel_conductor(ci, eta[2], k[2]) * B[p + 8])
        return (-wi[0], -wi[1], wi[2]), w, 1.0, 1.0, True
    dist = int(B[o + IF_DIST])
    masking = int(B[o + IF_MASK])
    au, av = B[p + 9], B[p + 10]
    wis = (wi[0], wi[1], ci)
    m = _normal(dist, au, av, wis, u0, u1)
    c = wis[0] * m[0] + wis[1] * m[1] + wis[2] * m[2]
    c2 = 2.0 * c
    wo = (c2 * m[0] - wi[0], c2 * m[1] - wi[1], (c2 * m[2] - ci) * s)
    co = wo[2] * s
    if not (c > 0.0 and co > 0.0):
        return wo, zero, 0.0, 0.0, False
    ti = _term(dist, masking, au, av, wis)
    to = _term(dist, masking, au, av, (wo[0], wo[1], co))
    g2 = _g2(dist, masking, ti, to, chi=True)
    if dist == mf.GGX:
        w1 = g2 * (1.0 + ti)                    # G2/G1(wi)
    else:
        w1 = g2 * c / (ci * m[2])               # G2·(wi·m)/(cos θi cos θm)
    pf = 1.0
    pr = 1.0
    if dens:
        D = mf.D(dist, au, av, m)
        if dist == mf.GGX:
            pf = D * (0.25 / ci) / (1.0 + ti)
            pr = D * (0.25 / co) / (1.0 + to)
        else:
            pf = D * m[2] * (0.25 / c)
            pr = pf
        if not pf > 0.0:                        # a density that underflowed: a failed sample
            return wo, zero, 0.0, 0.0, False
    w = (fresnel_conductor(c, eta[0], k[0]) * B[p + 6] * w1, fresnel_conductor(c, eta[1], k[1]) * B[p + 7] * w1,
         fresnel_conductor(c, eta[2], k[2]) * B[p + 8] * w1)
    return wo, w, pf, pr, False


@kernel(error_model="numpy")
def _conductor_eval(B, o, wi, wo, ti, to, pdf_only):
    p = o + IF_P
    zero = (0.0, 0.0, 0.0)
    if B[p + 11] > 0.0:
        return zero, 0.0, 0.0
    s = -1.0 if wi[2] < 0.0 else 1.0
    ci = wi[2] * s
    co = wo[2] * s
    if not (ci > 0.0 and co > 0.0):
        return zero, 0.0, 0.0
    hx, hy, hz = wi[0] + wo[0], wi[1] + wo[1], ci + co
    l2 = hx * hx + hy * hy + hz * hz
    inv = 1.0 / math.sqrt(l2) if l2 > 0.0 else 1.0
    h = (hx * inv, hy * inv, hz * inv)
    cih = wi[0] * h[0] + wi[1] * h[1] + ci * h[2]
    if not cih > 0.0:
        return zero, 0.0, 0.0
    dist = int(B[o + IF_DIST])
    masking = int(B[o + IF_MASK])
    au, av = B[p + 9], B[p + 10]
    D = mf.D(dist, au, av, h)
    if dist == mf.GGX:
        if not ti >= 0.0:
            ti = _term(dist, masking, au, av, wi)
        if not to >= 0.0:
            to = _term(dist, masking, au, av, wo)
        pf = D * (0.25 / ci) / (1.0 + ti)
        pr = D * (0.25 / co) / (1.0 + to)
    else:
        pf = D * h[2] * (0.25 / cih)
        pr = pf
    if pdf_only:
        return zero, pf, pr
    if not ti >= 0.0:
        ti = _term(dist, masking, au, av, wi)
    if not to >= 0.0:
        to = _term(dist, masking, au, av, wo)
    v = D * _g2(dist, masking, ti, to, chi=True) * (0.25 / ci)
    eta = (B[p], B[p + 1], B[p + 2])
    k = (B[p + 3], B[p + 4], B[p + 5])
    return ((fresnel_conductor(cih, eta[0], k[0]) * B[p + 6] * v, fresnel_conductor(cih, eta[1], k[1]) * B[p + 7] * v,
             fresnel_conductor(cih, eta[2], k[2]) * B[p + 8] * v), pf, pr)


@kernel(error_model="numpy")
def _dielectric_sample(B, o, wi, u0, u1, u2, dens):
    p = o + IF_P
    zero = (0.0, 0.0, 0.0)
    ci = wi[2]
    if ci == 0.0:
        return (0.0, 0.0, 1.0), zero, 0.0, 0.0, False
    eta = B[p]
    tint = (B[p + 1], B[p + 2], B[p + 3])
    if B[p + 6] > 0.0:        # smooth
        F, cos_t, e = fresnel_dielectric(ci, eta)
        if u2 < F:
            return (-wi[0], -wi[1], ci), (1.0, 1.0, 1.0), 1.0, 1.0, True
        return (-wi[0] / e, -wi[1] / e, cos_t), tint, 1.0, 1.0, True
    dist = int(B[o + IF_DIST])
    masking = int(B[o + IF_MASK])
    au, av = B[p + 4], B[p + 5]
    side = -1.0 if ci < 0.0 else 1.0
    m = _normal(dist, au, av, (wi[0] * side, wi[1] * side, ci * side), u0, u1)
    cim = wi[0] * m[0] + wi[1] * m[1] + ci * m[2]
    F, cos_t, e = fresnel_dielectric(cim, eta)      # e = n(transmitted side)/n(incident side)
    choose_r = u2 < F
    if choose_r:
        ka = 2.0 * cim
        kb = -1.0
        coh = cim
    else:
        kb = -1.0 / e
        ka = cim / e + cos_t
        coh = cos_t
    wo = (ka * m[0] + kb * wi[0], ka * m[1] + kb * wi[1], ka * m[2] + kb * ci)
    co = wo[2]
    cc = co * ci
    # The chosen lobe must land on its side, on a microfacet facing the incident direction.
    side_ok = cc > 0.0 if choose_r else (cc < 0.0 and cos_t != 0.0)
    if not (cim * ci > 0.0 and side_ok):
        return wo, zero, 0.0, 0.0, False
    chi_o = coh * co > 0.0
    ti = _term(dist, masking, au, av, wi)
    to = _term(dist, masking, au, av, wo)
    g2 = _g2(dist, masking, ti, to, chi_o)
    aci = abs(ci)
    acih = abs(cim)
    if dist == mf.GGX:
        w1 = g2 * (1.0 + ti)                        # G2/G1(wi)
    else:
        w1 = g2 * acih / (aci * m[2])               # G2·|wi·m|/(|cos θi| cos θm)
    pf = 1.0
    pr = 1.0
    if dens:
        D = mf.D(dist, au, av, m)
        acoh = abs(coh)
        den = cim + e * coh
        inv_d2 = 1.0 / (den * den)
        Fs = F if choose_r else 1.0 - F
        if dist == mf.GGX:
            ph_i = acih * D / (aci * (1.0 + ti))
            ph_o = acoh * D / (abs(co) * (1.0 + to)) if chi_o else 0.0
        else:
            ph_i = D * m[2]
            ph_o = ph_i if chi_o else 0.0
        if choose_r:
            pf = Fs * ph_i * (0.25 / acoh)
            pr = Fs * ph_o * (0.25 / acih)
        else:
            pf = Fs * ph_i * (e * e * acoh * inv_d2)
            pr = Fs * ph_o * (acih * inv_d2)
        if not pf > 0.0:                            # a density that underflowed: a failed sample
            return wo, zero, 0.0, 0.0, False
    if choose_r:
        return wo, (w1, w1, w1), pf, pr, False
    return wo, (w1 * tint[0], w1 * tint[1], w1 * tint[2]), pf, pr, False


@kernel(error_model="numpy")
def _dielectric_eval(B, o, wi, wo, ti, to, pdf_only):
    """Walter et al. 2007 (importance transport) with the densities of the sampler from each side.
    With e = n(wo side)/n(wi side), h ∝ wi + e'·wo (e' = 1 for a reflection) and
    den = wi·h + e·wo·h, both lobes share one form:
        value = F'·D·G2/|cos i| · j_v,   pf = F'·p_h(wi)·j_f,   pr = F'·p_h(wo)·j_r,
    with F' = F or 1 − F and j_v = 1/4 | |wi·h|·e²|wo·h|/den², j_f = 1/(4|wo·h|) | e²|wo·h|/den²,
    j_r = 1/(4|wi·h|) | |wi·h|/den² (reflection | transmission)."""
    p = o + IF_P
    zero = (0.0, 0.0, 0.0)
    if B[p + 6] > 0.0:
        return zero, 0.0, 0.0
    eta = B[p]
    ci = wi[2]
    co = wo[2]
    cc = ci * co
    refl = cc > 0.0
    e = eta if ci > 0.0 else 1.0 / eta
    ew = 1.0 if refl else e
    hx, hy, hz = wi[0] + ew * wo[0], wi[1] + ew * wo[1], ci + ew * co
    l2 = hx * hx + hy * hy + hz * hz
    inv = (-1.0 if hz < 0.0 else 1.0) / math.sqrt(l2 if l2 > 0.0 else 1.0)
    h = (hx * inv, hy * inv, hz * inv)
    if not h[2] > 0.0:
        return zero, 0.0, 0.0
    cih = wi[0] * h[0] + wi[1] * h[1] + ci * h[2]
    coh = wo[0] * h[0] + wo[1] * h[1] + co * h[2]
    ch = cih * coh
    r_ok = refl and ch > 0.0
    t_ok = cc < 0.0 and ch < 0.0
    if not (r_ok or t_ok):
        return zero, 0.0, 0.0
    dist = int(B[o + IF_DIST])
    masking = int(B[o + IF_MASK])
    au, av = B[p + 4], B[p + 5]
    F = fresnel_dielectric(cih, eta)[0]
    D = mf.D(dist, au, av, h)
    chi_i = cih * ci > 0.0
    chi_o = coh * co > 0.0
    acih = abs(cih)
    acoh = abs(coh)
    den = cih + e * coh
    inv_d2 = 1.0 / (den * den) if den != 0.0 else 0.0
    e2 = e * e
    Fs = F if r_ok else 1.0 - F
    if dist == mf.GGX:
        if not ti >= 0.0:
            ti = _term(dist, masking, au, av, wi)
        if not to >= 0.0:
            to = _term(dist, masking, au, av, wo)
        ph_i = acih * D / (abs(ci) * (1.0 + ti)) if chi_i else 0.0
        ph_o = acoh * D / (abs(co) * (1.0 + to)) if chi_o else 0.0
    else:
        ph = D * h[2]
        ph_i = ph if chi_i else 0.0
        ph_o = ph if chi_o else 0.0
    if r_ok:
        pf = Fs * ph_i * (0.25 / acoh) if acoh > 0.0 else 0.0
        pr = Fs * ph_o * (0.25 / acih) if acih > 0.0 else 0.0
    else:
        pf = Fs * ph_i * (e2 * acoh * inv_d2)
        pr = Fs * ph_o * (acih * inv_d2)
    if pdf_only:
        return zero, pf, pr
    if not ti >= 0.0:
        ti = _term(dist, masking, au, av, wi)
    if not to >= 0.0:
        to = _term(dist, masking, au, av, wo)
    jv = 0.25 if r_ok else acih * e2 * acoh * inv_d2
    v = Fs * D * _g2(dist, masking, ti, to, chi_i and chi_o) * jv / abs(ci)
    if t_ok:
        return (v * B[p + 1], v * B[p + 2], v * B[p + 3]), pf, pr
    return (v, v, v), pf, pr


# ----------------------------------------------------------------------------- dispatch
@kernel(error_model="numpy")
def _sample_local(B, o, wi, u0, u1, u2, dens):
    kind = B[o + IF_KIND]
    if kind == DIELECTRIC:
        return _dielectric_sample(B, o, wi, u0, u1, u2, dens)
    if kind == CONDUCTOR:
        return _conductor_sample(B, o, wi, u0, u1, dens)
    if kind == DIFFUSE:
        r = math.sqrt(u0)
        c, sn = cos_sin_turns(u1)
        z = math.sqrt(max(0.0, 1.0 - u0))
        side = -1.0 if wi[2] < 0.0 else 1.0
        wo = (r * c, r * sn, z * side)
        if wi[2] == 0.0 or not z > 0.0:
            return wo, (0.0, 0.0, 0.0), 0.0, 0.0, False
        p = o + IF_P
        return wo, (B[p], B[p + 1], B[p + 2]), z * INV_PI, abs(wi[2]) * INV_PI, False
    # NULL: index-matched pass-through
    p = o + IF_P
    if wi[2] == 0.0:
        return (-wi[0], -wi[1], -wi[2]), (0.0, 0.0, 0.0), 1.0, 1.0, True
    return (-wi[0], -wi[1], -wi[2]), (B[p], B[p + 1], B[p + 2]), 1.0, 1.0, True


@kernel(error_model="numpy")
def sample(B, o, wi, u0, u1, u2, dens):
    """(wo, weight f·|cos θo|/p (RGB), pf, pr, delta): importance transport. ``dens``: compute
    the densities (walks whose vertices feed MIS weights); otherwise pf = pr = 1 placeholders.
    A failed sample has weight 0."""
    if B[o + IF_FRAMED] <= 0.0:
        return _sample_local(B, o, wi, u0, u1, u2, dens)
    li = _local(B, o, wi)
    lo, w, pf, pr, delta = _sample_local(B, o, li, u0, u1, u2, dens)
    wo = _world(B, o, lo)
    if not (li[2] * wi[2] > 0.0 and lo[2] * wo[2] > 0.0):
        return wo, (0.0, 0.0, 0.0), 0.0, 0.0, delta
    return wo, w, pf, pr, delta


@kernel(error_model="numpy")
def evaluate(B, o, wi, wo, ti, to, pdf_only):
    """(f(wi → wo)·|cos θo| RGB (importance transport), pf = p(wo | wi), pr = p(wi | wo)) of the
    non-delta part. ``ti``/``to``: the masking terms of wi and wo if known (``term``), else NaN.
    ``pdf_only``: the densities alone (value 0)."""
    kind = B[o + IF_KIND]
    zero = (0.0, 0.0, 0.0)
    if kind == NULL or B[o + IF_DELTA] > 0.0:
        return zero, 0.0, 0.0
    framed = B[o + IF_FRAMED] > 0.0
    a = wi
    b = wo
    if framed:
        a = _local(B, o, wi)
        b = _local(B, o, wo)
        if not (a[2] * wi[2] > 0.0 and b[2] * wo[2] > 0.0):
            return zero, 0.0, 0.0
    if kind == DIELECTRIC:
        return _dielectric_eval(B, o, a, b, ti, to, pdf_only)
    if kind == CONDUCTOR:
        return _conductor_eval(B, o, a, b, ti, to, pdf_only)
    # DIFFUSE
    if not a[2] * b[2] > 0.0:
        return zero, 0.0, 0.0
    co = abs(b[2]) * INV_PI
    p = o + IF_P
    return (B[p] * co, B[p + 1] * co, B[p + 2] * co), co, abs(a[2]) * INV_PI
