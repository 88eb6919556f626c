"""A closed-form MIS density for a layer stack (pdf kind ``"lobes"``): reflections, and
transmissions through at most one rough interface.

The pdf of a layered BSDF serves only the MIS weights: light sampling and BSDF sampling must use
the same function of the direction, which need not be the sampler's true density (a poor one
costs variance, never bias). The approximate pdf (estimators.pdf_pair) estimates the sampler's
density on the stack without media by two short random walks and their connections: 3–4 µs on
two slabs, about 30 % of a two-slab render. This one adds, in closed form, one lobe per interface
the sampler can reach:

    p(wo | wi) = p_0(wo | wi)                      the entry interface, exact (estimators.single)
               + Σ_k W_k · lobe_k(wo | wi)         every inner interface k that reflects
               + pdf_constant

W_k is the probability that the sampler gets to interface k and back out along the specular
chain of wi and wo: the interfaces' transmission choices (1 − F at the macro-surface angle, the
walk's Fresnel choice; a conductor or diffuse interface is opaque) and the slabs' channel-mean
transmittance (media removed, as in the approximate pdf). lobe_k:
* every interface above k smooth (a sharp refraction chain): interface k's own reflection
  density between wi and wo refracted into its slab (iface.evaluate: its distribution, masking,
  anisotropy and normal map), times the solid-angle Jacobian of the chain
  dω_in/dω_out = (η_out/η_slab)² |cos θo| / |cos θ_in|;
* some interface above k rough: the refractions spread the lobe. It is taken as an anisotropic
  GGX reflection lobe around the outer mirror direction whose squared roughness adds, per
  axis, interface k's roughness seen from outside, α η_slab/η_out (near the normal an angle in
  the slab appears η_slab/η_out times larger outside), and for every rough dielectric crossed on
  the way in and out α_j²·(η_below − η_above)²/(4 η_out²) (α_j² the mean of its two axes; a
  facet tilt θ turns the refracted ray by θ(1 − η_above/η_below), half of which is the tilt of
  an equivalent reflecting facet) — the variances of small angles add;
* a diffuse interface: its cosine lobe seen through the chain, (η_out/η_slab)² |cos θo|/π.
Left out: paths with more than one inner reflection, and the media's scattering (the constant
stands for them, as in the approximate pdf).

Transmissions (``transmission``): with at most one rough interface on the way through, the
sampler's density of the straight-through paths in closed form (the same chain, the rough
interface's own transmission density, the Jacobian of the refractions after it). With several
rough interfaces their spreads convolve and the approximate pdf is used (estimators.pdf_pair).
Cost and the noise it gives the images: docs/benchmarks.md.
"""
from __future__ import annotations

import math

from .. import microfacet as mf
from ..fresnel import dielectric as fresnel_dielectric
from ..jit import kernel
from ..materials import CONDUCTOR, DIELECTRIC, DIFFUSE
from . import iface as ki
from .table import H_ETA_BOTTOM, H_ETA_SLAB, H_ETA_TOP, H_N, HEAD
from .walk import GRAZING, transmittance

from ..consts import INV_PI
NAN = math.nan


@kernel(error_model="numpy")
def _slab_pass(B, FT, s, d):
    """The channel-mean transmittance of slab s across its whole depth along d (media removed,
    as in the approximate pdf's pass probability)."""
    T = transmittance(B, FT, s, d, 0.0, -1.0 if d[2] > 0.0 else 1.0)
    return (T[0] + T[1] + T[2]) / 3.0


@kernel(error_model="numpy")
def _into(w, r, sign):
    """w (outside, pointing away from the stack) refracted into a medium of index η_out/r along
    the flat interfaces (Snell: the tangential part scales by r), pointing the same way; z = 0
    under total internal reflection."""
    x = w[0] * r
    y = w[1] * r
    s2 = x * x + y * y
    if s2 >= 1.0:
        return (x, y, 0.0)
    return (x, y, sign * math.sqrt(1.0 - s2))


@kernel(error_model="numpy")
def _outer_lobe(a, b, sign, au2, av2):
    """The density of an anisotropic GGX reflection lobe (squared roughnesses au2, av2 along the
    stack's x and y) at b given a, both outside on the side ``sign``: D(h)·cos θh/(4|a·h|)."""
    hx = a[0] + b[0]
    hy = a[1] + b[1]
    hz = (a[2] + b[2]) * sign
    l2 = hx * hx + hy * hy + hz * hz
    if not l2 > 0.0:
        return 0.0
    inv = 1.0 / math.sqrt(l2)
    h = (hx * inv, hy * inv, hz * inv)
    cah = abs(a[0] * h[0] + a[1] * h[1] + a[2] * sign * h[2])
    if not cah > 0.0:
        return 0.0
    return mf.D(mf.GGX, math.sqrt(au2), math.sqrt(av2), h) * h[2] * (0.25 / cah)


@kernel(error_model="numpy")
def inner_reflections(B, FT, a, b):
    """Σ_k W_k · lobe_k(b | a) over the inner interfaces (see the module docstring) of a
    reflection query (a, b on the same side)."""
    N = int(B[H_N])
    top = a[2] > 0.0
    sign = 1.0 if top else -1.0
    eta_out = B[H_ETA_TOP] if top else B[H_ETA_BOTTOM]
    w = 1.0
    spread = 0.0
    out = 0.0
    for step in range(N - 1):
        # Cross interface l (from the entry side) into slab s, towards interface k.
        l = step if top else N - 1 - step
        k = l + 1 if top else l - 1
        s = l if top else l - 1
        o = HEAD + l * ki.STRIDE
        kind = B[o + ki.IF_KIND]
        if kind == CONDUCTOR or kind == DIFFUSE:
            break
        eta_s = B[H_ETA_SLAB + s]
        r = eta_out / eta_s
        ta = _into(a, r, sign)
        tb = _into(b, r, sign)
        if not (abs(ta[2]) >= GRAZING and abs(tb[2]) >= GRAZING):
            break
        if kind == DIELECTRIC:
            # The cosines on the entry side of l (where the walk chooses), from the slab before.
            eta_e = eta_out if step == 0 else B[H_ETA_SLAB + (s - 1 if top else s + 1)]
            re = eta_out / eta_e
            ea = _into(a, re, sign)
            eb = _into(b, re, sign)
            eta_rel = B[o + ki.IF_P]
            w *= (1.0 - fresnel_dielectric(ea[2], eta_rel)[0]) * (1.0 - fresnel_dielectric(eb[2], eta_rel)[0])
            if not ki.is_delta(B, o):
                au, av = ki.alphas(B, o)
                de = (eta_s - eta_e) / eta_out
                g = 0.25 * de * de
                spread += (au * au + av * av) * g      # both crossings, the mean of the two axes
        w *= _slab_pass(B, FT, s, ta) * _slab_pass(B, FT, s, tb)
        if not w > 1e-12:
            break
        # Reflection at interface k.
        ok = HEAD + k * ki.STRIDE
        kk = B[ok + ki.IF_KIND]
        jac = r * r * abs(b[2]) / abs(tb[2])
        if kk == DIFFUSE:
            out += w * r * r * abs(b[2]) * INV_PI
            break
        if not (kk == CONDUCTOR or kk == DIELECTRIC):
            continue            # NULL: index-matched, the walk passes
        if spread <= 0.0:
            _, pf, _ = ki.evaluate(B, ok, ta, tb, NAN, NAN, pdf_only=True)
            out += w * pf * jac
        else:
            choose = 1.0
            if kk == DIELECTRIC:
                choose = fresnel_dielectric(ta[2], B[ok + ki.IF_P])[0]
            au2 = 0.0
            av2 = 0.0
            if not ki.is_delta(B, ok):
                au, av = ki.alphas(B, ok)
                m = eta_s / eta_out
                au2 = au * au * m * m
                av2 = av * av * m * m
            out += w * choose * _outer_lobe(a, b, sign, au2 + spread, av2 + spread)
    return out


@kernel(error_model="numpy")
def _chain_dir(B, a, b, top, eta_a, eta_b, j, s):
    """The direction in slab s of the transmission chain whose only rough interface is j: a's
    refraction (pointing back to a's side) before j, b's (pointing on to b's side) after it."""
    eta_s = B[H_ETA_SLAB + s]
    before = (s < j) if top else (s >= j)
    if before:
        return _into(a, eta_a / eta_s, 1.0 if top else -1.0), True
    return _into(b, eta_b / eta_s, -1.0 if top else 1.0), False


@kernel(error_model="numpy")
def transmission(B, FT, a, b):
    """(density, exact) of a transmission query (a, b on opposite sides). With at most one rough
    interface j on the way through (the others smooth dielectrics or null), the sampler's density
    in closed form: every interface's transmission choice (1 − F at the chain's angle; interface
    j's own density includes its choice) and every slab's channel-mean transmittance along the
    chain, interface j's density between a refracted down to it and b refracted up to it, and the
    Jacobian of the refractions after j, (η_b/η_after j)² |cos θb| / |cos θ after j|; 0 when every
    interface is smooth (a delta path). ``exact`` False: several rough interfaces (their spreads
    convolve; the caller uses the approximate pdf) or an opaque one."""
    N = int(B[H_N])
    top = a[2] > 0.0
    eta_a = B[H_ETA_TOP] if top else B[H_ETA_BOTTOM]
    eta_b = B[H_ETA_BOTTOM] if top else B[H_ETA_TOP]
    j = -1
    for l in range(N):
        o = HEAD + l * ki.STRIDE
        kind = B[o + ki.IF_KIND]
        if kind == CONDUCTOR or kind == DIFFUSE:
            return 0.0, False
        if kind == DIELECTRIC and not ki.is_delta(B, o):
            if j >= 0:
                return 0.0, False
            j = l
    if j < 0:
        return 0.0, True
    w = 1.0
    for l in range(N):
        o = HEAD + l * ki.STRIDE
        # The chain's directions on both sides of interface l (outside: a or b themselves).
        s_in = (l - 1) if top else l          # the slab on the entry side of l (−1 / N−1: outside)
        s_out = l if top else l - 1
        if (top and l == 0) or ((not top) and l == N - 1):
            d_in = a
            in_a = True
        else:
            d_in, in_a = _chain_dir(B, a, b, top, eta_a, eta_b, j, s_in)
        if (top and l == N - 1) or ((not top) and l == 0):
            d_out = b
        else:
            d_out, _ = _chain_dir(B, a, b, top, eta_a, eta_b, j, s_out)
        if not (abs(d_in[2]) >= GRAZING and abs(d_out[2]) >= GRAZING):
            return 0.0, True                  # total internal reflection on the chain
        if l == j:
            _, pf, _ = ki.evaluate(B, o, d_in, d_out, NAN, NAN, pdf_only=True)
            w *= pf
        elif B[o + ki.IF_KIND] == DIELECTRIC:
            # The choice at the angle on its entry side (a's chain) or exit side (b's chain; the
            # same Fresnel reflectance by reciprocity).
            if in_a:
                w *= 1.0 - fresnel_dielectric(d_in[2], B[o + ki.IF_P])[0]
            else:
                w *= 1.0 - fresnel_dielectric(d_out[2], B[o + ki.IF_P])[0]
        s = s_out
        if 0 <= s <= N - 2:
            w *= _slab_pass(B, FT, s, d_out)
        if not w > 0.0:
            return 0.0, True
    # From the direction just after j out to b.
    s_after = j if top else j - 1
    if 0 <= s_after <= N - 2:
        r = eta_b / B[H_ETA_SLAB + s_after]
        t = _into(b, r, 1.0)
        w *= r * r * abs(b[2]) / abs(t[2])
    return w, True
