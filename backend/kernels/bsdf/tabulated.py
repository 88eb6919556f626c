"""A uniform layered stack from its table: the light that enters the stack as a Fourier series over
the azimuth (solved once by adding-doubling, backend/layered/tabulated.py), the top interface's
own reflection exactly (as the walk's), and a sampler whose density is exact.

Directions: wi, wo above the surface (the stack is opaque and two-sided). The part of the light
that entered is tabulated as a kernel of propagation directions: travelling down at μ1 inside
the top medium (or outside, for a rough top), leaving up at μ2, azimuth difference Δ (0: the
mirror direction). For each pair of nodes (j in, i out; uniform in θ, backend/layered/tabulated.py) the table holds
y_m(j → i) = x_m/μ_i per channel, with x the flux kernel (importance transport: the flux density
per steradian leaving towards i per unit flux arriving from j), so

  x(μ1 → μ2, Δ) = μ2 · Σ_m y_m(μ1 → μ2) cos(mΔ),  y bilinear in (μ1, μ2) between nodes
                  (clamped at the outermost nodes).

Top interface, two modes:
* ``SMOOTH_TOP`` (smooth, index-matched, or α ≤ ALPHA_SMOOTH in backend/layered/tabulated.py):
  the table is in the top medium's directions; wi and wo refract through the top exactly (Snell),
  with the Fresnel transmittance (1 − F)·tint each way and the exit's solid-angle compression
  cos θo/(η² μ2); the top's own reflection is its delta mirror (smooth) or its rough lobe (the
  dielectric BSDF, kernels/bsdf/dielectric.py) for a near-smooth top. The sharpest part of such
  a stack, the single reflection at the first interface below the top slab (a coated metal's
  highlight), is evaluated exactly too (``_first``), and the table holds the rest.
* ``ROUGH_TOP``: the top's refractions are inside the table (outside directions), and its own
  reflection lobe is added exactly.

Sampling: the top's reflection with probability w_s = Rs/(Rs + A) (Rs its directional albedo, A
the table part's, both interpolated in θi between the sampling nodes; at least 20 % for a sharp
top, as kernels/bsdf/coated_diffuse.specular_share explains), else a direction from the
table part's own piecewise-constant distribution: per sampling node (uniform in θi), cells
uniform in θo × Δ bins over [0, π] (either sign), probabilities ∝ the table part integrated
over the cell; the two nodes around θi are mixed with their interpolation weights. A rough top's
reflection that points below the surface is mirrored up (coated_diffuse.top_density). pdf and
weights (eval/pdf) are exact for this BSDF; the tables' own error against the walk is measured in
tests/test_tabulated.py.

Block layout (``T[o:]``, the H_* offsets; arrays at the offsets stored in the head):
  H_N, H_M                  Gauss–Legendre nodes per hemisphere, Fourier orders
  H_MODE, H_ETA             SMOOTH_TOP / ROUGH_TOP, the top's relative index
  H_ALPHA, H_DIST, H_MASK   the top's roughness (0: smooth), microfacet codes
  H_TINT                    the top's transmission tint (RGB)
  H_SI, H_SO, H_SB          sampling nodes in θi, θo cells, Δ bins
  H_MU, H_Y                 the nodes (n), y packed per node pair: the orders 0 … count − 1 of
  H_YOFF, H_YCNT            pair (j, i) (× 3 channels) from offset YOFF[j·n + i]; the orders
                            beyond a pair's count are below 1e-4 of its order 0 (or negligible
                            altogether), which keeps a sharp stack's table at a fifth
  H_F1 …                    a smooth top: the first interface below it (its kind, NO_FIRST when the
                            table holds it, microfacet codes, 12 parameters as kernels/materials.bind)
                            and the top slab's optical depth (RGB), for its exact single reflection
  H_BODY, H_G, H_H, H_RBAR  a textured diffuse body (1): y is for a black body, and its albedo ρ
                            (per lane) adds ρ·G(μ1)·H(μ2)/(1 − ρ·r̄) per channel to order 0 of y
                            (G, H: 3 × n over the nodes; r̄: 3; backend/layered/tabulated.py
                            ``_body_factors``); H_KBODY: per sampling node the albedo a white
                            body adds (3), so the albedo is ALB + ρ·K·(1 − r̄)/(1 − ρ·r̄)
  H_CDF, H_ALB, H_RS         per sampling node: running sums over the SO·SB cells (SO·SB + 1),
                            the table part's albedo (RGB), the top's reflection albedo (head slot 18
                            is unused: until 2026-12-07 it placed the share of the top's reflections
                            below the surface, which the sampler no longer needs: ``top_density``)
"""
from __future__ import annotations

import math

from . import IMPORTANCE
from . import conductor, dielectric, diffuse
from .coated_diffuse import (BODY, SHARP_ALPHA, TOP_DELTA, specular_share, top_density, top_lobe_sample,
                             top_or_body)
from ..fresnel import dielectric as fresnel
from ..jit import inlined, kernel
from ..turns import cos_sin_turns

SMOOTH_TOP, ROUGH_TOP = 0, 1
H_N, H_M, H_MODE, H_ETA, H_ALPHA, H_DIST, H_MASK, H_TINT = 0, 1, 2, 3, 4, 5, 6, 7
H_SI, H_SO, H_SB, H_MU, H_Y, H_CDF, H_ALB, H_RS = 10, 11, 12, 13, 14, 15, 16, 17
H_F1, H_F1_DIST, H_F1_MASK, H_TAU0, H_F1_P = 19, 20, 21, 22, 25
H_YOFF, H_YCNT = 37, 38
H_BODY, H_G, H_H, H_RBAR, H_KBODY = 39, 40, 41, 42, 43
HEAD = 48
NO_FIRST, FIRST_DIFFUSE, FIRST_CONDUCTOR, FIRST_DIELECTRIC = -1.0, 0.0, 1.0, 2.0   # H_F1
ZERO3 = (0.0, 0.0, 0.0)
HALF_PI = 0.5 * math.pi


# ----------------------------------------------------------------------------- the table part
@kernel
def _bracket(T, a, n, mu):
    """(k, t): mu between nodes k and k + 1 with weight t of k + 1 (clamped to the end nodes)."""
    if mu <= T[a]:
        return 0, 0.0
    if mu >= T[a + n - 1]:
        return n - 2, 1.0
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if T[a + mid] <= mu:
            lo = mid
        else:
            hi = mid
    return lo, (mu - T[a + lo]) / (T[a + lo + 1] - T[a + lo])


@kernel
def _pole(T, mu_at, n, mu):
    """Between the last node and the pole the m-th coefficient of a smooth function on the sphere
    shrinks as sin^m θ: the factor per order (1 below the last node)."""
    last = T[mu_at + n - 1]
    if mu <= last:
        return 1.0
    return math.sqrt(max(1.0 - mu * mu, 0.0) / max(1.0 - last * last, 1e-300))


@kernel
def series(T, o, mu1, mu2, cos_d):
    """x(μ1 → μ2, Δ) per channel (the module docstring), cos_d = cos Δ."""
    n = int(T[o + H_N])
    mu_at = o + int(T[o + H_MU])
    y = o + int(T[o + H_Y])
    yoff = o + int(T[o + H_YOFF])
    ycnt = o + int(T[o + H_YCNT])
    j, tj = _bracket(T, mu_at, n, mu1)
    i, ti = _bracket(T, mu_at, n, mu2)
    shrink = _pole(T, mu_at, n, mu1) * _pole(T, mu_at, n, mu2)
    w00 = (1.0 - tj) * (1.0 - ti)
    w01 = (1.0 - tj) * ti
    w10 = tj * (1.0 - ti)
    w11 = tj * ti
    k00 = j * n + i
    k10 = k00 + n
    p00 = y + int(T[yoff + k00])
    p01 = y + int(T[yoff + k00 + 1])
    p10 = y + int(T[yoff + k10])
    p11 = y + int(T[yoff + k10 + 1])
    c00 = int(T[ycnt + k00])
    c01 = int(T[ycnt + k00 + 1])
    c10 = int(T[ycnt + k10])
    c11 = int(T[ycnt + k10 + 1])
    M = max(max(c00, c01), max(c10, c11))
    r = g = b = 0.0
    # c = cos(mΔ)·shrink^m: the recurrence cos((m+1)Δ) = 2 cos Δ cos mΔ − cos((m−1)Δ), scaled
    c_prev = cos_d / shrink if shrink > 0.0 else 0.0
    c = 1.0
    two_c = 2.0 * cos_d * shrink
    s2 = shrink * shrink
    for m in range(M):
        k = 3 * m
        if m < c00:
            r += c * w00 * T[p00 + k]
            g += c * w00 * T[p00 + k + 1]
            b += c * w00 * T[p00 + k + 2]
        if m < c01:
            r += c * w01 * T[p01 + k]
            g += c * w01 * T[p01 + k + 1]
            b += c * w01 * T[p01 + k + 2]
        if m < c10:
            r += c * w10 * T[p10 + k]
            g += c * w10 * T[p10 + k + 1]
            b += c * w10 * T[p10 + k + 2]
        if m < c11:
            r += c * w11 * T[p11 + k]
            g += c * w11 * T[p11 + k + 1]
            b += c * w11 * T[p11 + k + 2]
        c_next = two_c * c - s2 * c_prev
        c_prev = c
        c = c_next
    return (max(r, 0.0) * mu2, max(g, 0.0) * mu2, max(b, 0.0) * mu2)


@kernel
def _cos_delta(wi, wo):
    """cos of the propagation azimuth difference: the light travels along −wi, then along wo."""
    a = wi[0] * wi[0] + wi[1] * wi[1]
    b = wo[0] * wo[0] + wo[1] * wo[1]
    if not (a > 1e-24 and b > 1e-24):
        return 1.0
    return -(wi[0] * wo[0] + wi[1] * wo[1]) / math.sqrt(a * b)


@kernel
def _inside(eta, mu):
    """(cos of the refracted direction inside the top medium (0: total reflection), 1 − F)."""
    F, ct, _ = fresnel(mu, eta)
    return abs(ct), 1.0 - F


@kernel
def _first(T, o, a, b):
    """The first interface below the top medium, reached without scattering (a smooth top): its
    own reflection between the refracted directions a → b (both pointing up, away from it),
    attenuated by the top slab both ways: the sharpest part of the stack, exact here."""
    kind = T[o + H_F1]
    p = o + H_F1_P
    dist = int(T[o + H_F1_DIST])
    masking = int(T[o + H_F1_MASK])
    if kind == FIRST_CONDUCTOR:
        v, _ = conductor.eval_pdf((T[p], T[p + 1], T[p + 2]), (T[p + 3], T[p + 4], T[p + 5]),
                                  (T[p + 6], T[p + 7], T[p + 8]), T[p + 9], T[p + 10], T[p + 11] > 0.0,
                                  dist, masking, a, b)
    elif kind == FIRST_DIELECTRIC:
        v, _ = dielectric.eval_pdf(T[p], (T[p + 1], T[p + 2], T[p + 3]), T[p + 4], T[p + 5], T[p + 6] > 0.0,
                                   dist, masking, IMPORTANCE, a, b)
    elif kind == FIRST_DIFFUSE:
        v, _ = diffuse.eval_pdf((T[p], T[p + 1], T[p + 2]), a, b)
    else:
        return ZERO3
    t = o + H_TAU0
    ia = 1.0 / max(a[2], 1e-300)
    ib = 1.0 / max(b[2], 1e-300)
    return (v[0] * math.exp(-T[t] * (ia + ib)), v[1] * math.exp(-T[t + 1] * (ia + ib)),
            v[2] * math.exp(-T[t + 2] * (ia + ib)))


@kernel
def _node_lerp(T, at, n, mu_at, mu):
    k, t = _bracket(T, mu_at, n, mu)
    return T[at + k] + t * (T[at + k + 1] - T[at + k])


@kernel
def _with_body(T, o, x, rho, mu1, mu2):
    """x plus a textured body's light: ρ·G(μ1)·H(μ2)·μ2/(1 − ρ·r̄) per channel."""
    if T[o + H_BODY] <= 0.0:
        return x
    n = int(T[o + H_N])
    mu_at = o + int(T[o + H_MU])
    g = o + int(T[o + H_G])
    h = o + int(T[o + H_H])
    rb = o + int(T[o + H_RBAR])
    out0 = x[0] + rho[0] * _node_lerp(T, g, n, mu_at, mu1) * _node_lerp(T, h, n, mu_at, mu2) * mu2 / max(1.0 - rho[0] * T[rb], 1e-3)
    out1 = x[1] + rho[1] * _node_lerp(T, g + n, n, mu_at, mu1) * _node_lerp(T, h + n, n, mu_at, mu2) * mu2 / max(1.0 - rho[1] * T[rb + 1], 1e-3)
    out2 = x[2] + rho[2] * _node_lerp(T, g + 2 * n, n, mu_at, mu1) * _node_lerp(T, h + 2 * n, n, mu_at, mu2) * mu2 / max(1.0 - rho[2] * T[rb + 2], 1e-3)
    return (max(out0, 0.0), max(out1, 0.0), max(out2, 0.0))


@kernel
def table_part(T, o, rho, wi, wo):
    """The flux kernel of the light that entered the stack, f·cos θo per channel (``rho``: a
    textured body's albedo at the lane)."""
    cd = _cos_delta(wi, wo)
    if T[o + H_MODE] == ROUGH_TOP:
        return _with_body(T, o, series(T, o, wi[2], wo[2], cd), rho, wi[2], wo[2])
    eta = T[o + H_ETA]
    m1, t1 = _inside(eta, wi[2])
    m2, t2 = _inside(eta, wo[2])
    if not (m1 > 0.0 and m2 > 0.0):
        return ZERO3
    x = _with_body(T, o, series(T, o, m1, m2, cd), rho, m1, m2)
    if T[o + H_F1] != NO_FIRST:
        a = (wi[0] / eta, wi[1] / eta, m1)
        b = (wo[0] / eta, wo[1] / eta, m2)
        f1 = _first(T, o, a, b)
        x = (x[0] + f1[0], x[1] + f1[1], x[2] + f1[2])
    s = t1 * t2 * wo[2] / (eta * eta * m2)
    tint = o + H_TINT
    return (x[0] * s * T[tint] * T[tint], x[1] * s * T[tint + 1] * T[tint + 1], x[2] * s * T[tint + 2] * T[tint + 2])


# ----------------------------------------------------------------------------- sampling tables
@kernel
def _node_weights(T, o, mu):
    """(node a, node b, weight of b) of the sampling nodes (uniform in θ on [0, π/2]) around μ."""
    si = int(T[o + H_SI])
    x = math.acos(min(max(mu, 0.0), 1.0)) / HALF_PI * (si - 1)
    k = min(int(x), si - 2)
    return k, k + 1, x - k


@kernel
def _per_node(T, o, h, mu):
    a, b, t = _node_weights(T, o, mu)
    at = o + int(T[o + h])
    return (1.0 - t) * T[at + a] + t * T[at + b]


@kernel
def _cell(T, o, wi, wo):
    """(cell index, cell solid angle) of wo relative to wi in the sampling grid."""
    so = int(T[o + H_SO])
    sb = int(T[o + H_SB])
    th = math.acos(min(max(wo[2], 0.0), 1.0))
    c = min(int(th / HALF_PI * so), so - 1)
    cd = min(max(_cos_delta(wi, wo), -1.0), 1.0)
    d = min(int(math.acos(cd) / math.pi * sb), sb - 1)
    lo = math.cos((c + 1) * HALF_PI / so)
    hi = math.cos(c * HALF_PI / so)
    return c * sb + d, (hi - lo) * 2.0 * math.pi / sb


@kernel
def _table_density(T, o, wi, wo):
    """Density of the table part's sampler at wo (both signs of Δ)."""
    if not wo[2] > 0.0:
        return 0.0
    a, b, t = _node_weights(T, o, wi[2])
    k, omega = _cell(T, o, wi, wo)
    cells = int(T[o + H_SO]) * int(T[o + H_SB])
    cdf = o + int(T[o + H_CDF])
    pa = T[cdf + a * (cells + 1) + k + 1] - T[cdf + a * (cells + 1) + k]
    pb = T[cdf + b * (cells + 1) + k + 1] - T[cdf + b * (cells + 1) + k]
    return ((1.0 - t) * pa + t * pb) / omega


@kernel
def _sample_table(T, o, wi, u0, u1, u2):
    """A direction from the table part's sampler (node by u2, cell by u0, inside the cell by the
    rest of u0 and by u1, which also picks the sign of Δ)."""
    a, b, t = _node_weights(T, o, wi[2])
    node = b if u2 < t else a
    so = int(T[o + H_SO])
    sb = int(T[o + H_SB])
    cells = so * sb
    base = o + int(T[o + H_CDF]) + node * (cells + 1)
    lo = 0
    hi = cells
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if T[base + mid] <= u0:
            lo = mid
        else:
            hi = mid
    w = T[base + lo + 1] - T[base + lo]
    x = min(max((u0 - T[base + lo]) / w, 0.0), 1.0) if w > 0.0 else 0.5
    c = lo // sb
    d = lo - c * sb
    m_hi = math.cos(c * HALF_PI / so)
    m_lo = math.cos((c + 1) * HALF_PI / so)
    mu = m_lo + x * (m_hi - m_lo)
    sign = 1.0
    v = u1 * 2.0
    if v >= 1.0:
        sign = -1.0
        v -= 1.0
    delta = sign * (d + v) * math.pi / sb
    # propagation azimuth of the incident light: that of −wi
    pi_ = math.atan2(-wi[1], -wi[0]) if (wi[0] != 0.0 or wi[1] != 0.0) else 0.0
    cp, sp = cos_sin_turns((pi_ + delta) / (2.0 * math.pi))
    st = math.sqrt(max(1.0 - mu * mu, 0.0))
    return (st * cp, st * sp, mu)


# ----------------------------------------------------------------------------- the BSDF
@kernel
def _top(T, o):
    eta = T[o + H_ETA]
    alpha = T[o + H_ALPHA]
    return eta, alpha, int(T[o + H_DIST]), int(T[o + H_MASK]), alpha <= 0.0


@kernel
def _rgb_per_node(T, o, h, mu):
    a, b, t = _node_weights(T, o, mu)
    at = o + int(T[o + h])
    return ((1.0 - t) * T[at + 3 * a] + t * T[at + 3 * b], (1.0 - t) * T[at + 3 * a + 1] + t * T[at + 3 * b + 1],
            (1.0 - t) * T[at + 3 * a + 2] + t * T[at + 3 * b + 2])


@kernel
def _table_albedo(T, o, rho, mu):
    """The table part's directional albedo per channel (interpolated between sampling nodes; a
    textured body's part for its albedo ρ)."""
    a = _rgb_per_node(T, o, H_ALB, mu)
    if T[o + H_BODY] <= 0.0:
        return a
    k = _rgb_per_node(T, o, H_KBODY, mu)
    rb = o + int(T[o + H_RBAR])
    return (a[0] + rho[0] * k[0] * (1.0 - T[rb]) / max(1.0 - rho[0] * T[rb], 1e-3),
            a[1] + rho[1] * k[1] * (1.0 - T[rb + 1]) / max(1.0 - rho[1] * T[rb + 1], 1e-3),
            a[2] + rho[2] * k[2] * (1.0 - T[rb + 2]) / max(1.0 - rho[2] * T[rb + 2], 1e-3))


@kernel
def more_light_samples(T, o):
    """Should next-event estimation take more light samples here (kernels/integrator.py
    TABLE_NEE)? Yes unless the top is (nearly) a mirror: BSDF sampling then finds the light's
    reflection, and more light samples only shift the MIS weights towards the worse strategy."""
    return T[o + H_ALPHA] > SHARP_ALPHA


@kernel
def _share(T, o, rho, mu):
    return specular_share(_per_node(T, o, H_RS, mu), _table_albedo(T, o, rho, mu), T[o + H_ALPHA])


@kernel
def eval_pdf(T, o, rho, wi, wo):
    """(f·cos θo RGB, pdf of ``sample``) of the non-delta part; 0 unless wi, wo are above.
    ``rho``: a textured body's albedo at the lane (unused otherwise)."""
    if not (wi[2] > 0.0 and wo[2] > 0.0):
        return ZERO3, 0.0
    eta, alpha, dist, masking, smooth = _top(T, o)
    f = table_part(T, o, rho, wi, wo)
    w_s = _share(T, o, rho, wi[2])
    pdf = (1.0 - w_s) * _table_density(T, o, wi, wo)
    if not smooth:
        fr, _ = dielectric.eval_pdf(eta, (1.0, 1.0, 1.0), alpha, alpha, smooth=False, dist=dist,
                                    masking=masking, mode=IMPORTANCE, wi=wi, wo=wo)
        f = (f[0] + fr[0], f[1] + fr[1], f[2] + fr[2])
        pdf += w_s * top_density(dist, alpha, alpha, wi, wo)
    return f, pdf


@kernel
def sample(T, o, rho, wi, u0, u1, u2):
    if not wi[2] > 0.0:
        return (0.0, 0.0, 1.0), ZERO3, 0.0, False
    eta, alpha, dist, masking, smooth = _top(T, o)
    w_s = _share(T, o, rho, wi[2])
    choice, wo, F, a, b, c = top_or_body(eta, smooth, dist, alpha, alpha, w_s, wi, u0, u1, u2)
    if choice == TOP_DELTA:
        return wo, (F, F, F), 0.0, True
    if choice == BODY:
        wo = _sample_table(T, o, wi, a, b, c)          # the table part's sampler
    if not wo[2] > 0.0:
        return wo, ZERO3, 0.0, False
    f, pdf = eval_pdf(T, o, rho, wi, wo)
    if not pdf > 0.0:
        return wo, ZERO3, 0.0, False
    return wo, (f[0] / pdf, f[1] / pdf, f[2] / pdf), pdf, False


@kernel
def albedo(T, o, rho, mu):
    """The directional albedo at cos θ = μ (the top's reflection + the table part's): the
    denoising AOV."""
    rs = _per_node(T, o, H_RS, mu)
    a = _table_albedo(T, o, rho, mu)
    return (a[0] + rs, a[1] + rs, a[2] + rs)


@kernel(nogil=True)
def eval_table_part(T, o, rho, wi, wo, out):
    """``table_part`` over arrays of directions (building the sampling tables)."""
    r = (rho[0], rho[1], rho[2])
    for k in range(wi.shape[0]):
        v = table_part(T, o, r, (wi[k, 0], wi[k, 1], wi[k, 2]), (wo[k, 0], wo[k, 1], wo[k, 2]))
        out[k, 0], out[k, 1], out[k, 2] = v


# ----------------------------------------------------------------------------- binding
# The kind's slots in a material row (kernels/materials.py ``MaterialTable.values``: its Python
# material packs them) and its lane parameters: the 12-tuple every kind binds to (one Numba type
# for all, kernels/materials.py ``bind``), written and read here only.
TAB, RHO = 3, 4        # its table block's offset, a textured body's colour (RGB)


@inlined
def params(tab, rho):
    return (tab, rho[0], rho[1], rho[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@inlined
def eval_pdf_p(T, p, wi, wo):
    return eval_pdf(T, int(p[0]), (p[1], p[2], p[3]), wi, wo)


@inlined
def sample_p(T, p, wi, u0, u1, u2):
    return sample(T, int(p[0]), (p[1], p[2], p[3]), wi, u0, u1, u2)


@inlined
def albedo_p(T, p, mu):
    return albedo(T, int(p[0]), (p[1], p[2], p[3]), mu)


@inlined
def sharp_top_p(T, p, wi, u0, u1):
    """For a rough top with α ≤ SHARP_ALPHA: (w_s, a direction from the top's lobe alone);
    w_s 0 for any other top (kernels/integrator.py ``_probe_lobe``)."""
    o = int(p[0])
    _, alpha, dist, _, smooth = _top(T, o)
    if smooth or not alpha <= SHARP_ALPHA or not wi[2] > 0.0:
        return 0.0, (0.0, 0.0, 1.0)
    return _share(T, o, (p[1], p[2], p[3]), wi[2]), top_lobe_sample(dist, alpha, alpha, wi, u0, u1)


@inlined
def smooth_reflectance_p(T, p, wi):
    """A smooth top's mirror, as ``top_or_body`` samples it (TOP_DELTA): F on average."""
    eta, _, _, _, smooth = _top(T, int(p[0]))
    return dielectric.smooth_reflectance(eta, smooth, wi)
