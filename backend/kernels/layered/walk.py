"""The random walk through a bound layer stack (Guo et al. 2018 §4.1), one lane.

Geometry: interface l (0 = top) lies at depth t = l; slab k fills k < t < k + 1 (normalised depth
s = t − k inside it: 0 = its top, 1 = its bottom). Directions are in the material's local frame
(z up); travelling along d changes t by −d_z per unit length. Optical depth per unit depth along
d is τ0·sigma_scale(d)/|d_z| (τ0 = σt × thickness; sigma_scale ≠ 1 for microflake media only).

Transport: every interface is sampled in IMPORTANCE mode, so a walk started from direction
``w0`` is a photon-like flux walk: its throughput after the exit vertex estimates
f(w0 → w_exit)·|cos w_exit| / p(w_exit) for light arriving from w0 (``sample``); the estimators
convert to the requested transport mode at the end.

Records (``purpose`` VALUE or PDF): one row per vertex of ``W[slot]`` (float64, fields ``F_*``),
with what the estimators need (directions point away from the vertex, as for BSDFs):
  kind (1 interface, 0 medium), layer (interface or slab index), t (depth),
  w_in / w_out (towards the previous vertex / the sampled next one; w_in of vertex 1 = start),
  thru0 / thru1 (throughput arriving / after the sampled direction; RGB, value walks),
  pdf_fwd (density of w_out given w_in; 1 for delta samples: a placeholder), delta,
  c1, c2, A, B (the vertex's MIS coefficients for the bidirectional connections),
  gamma, qbg, rev (pdf walks: the walk's weight in the pdf integrand — 1/survival probabilities
  and, for the approximate pdf, slab pass probabilities — and its products with the running pdf
  ratios), sig_in / sig_out (extinction scales of w_in's and w_out's travel directions; an
  interface vertex's sig_out is NaN until its flight into a directional medium computes it, so
  the connections reuse it instead of recomputing the microflake projected area),
  and the unfolded quantities (pdf_rev, the edge densities, P, Q) tests recompute.

MIS recurrences (the paper's appendix B, folded): with inv_dens = 1/dens_fwd (0 for the first
vertex), own = ¬δ, ipf = 1/pdf_fwd and dens_rev the reverse density of the previous vertex's
depth along the edge into this one, vertex i has
    a_i  = (own_{i−1} + dens_rev_i·b1_{i−1})·ipf_{i−1},   b1_i = inv_dens_i·(own_i + pdf_rev_i·a_i),
    qb_i = inv_dens_i·dens_rev_i·pdf_rev_{i−1}·qb_{i−1}·ipf_{i−1}   (qb_1 = 1),
and c1 = inv_dens, c2 = inv_dens·a, A = ipf·own, B = ipf·b1 (clamped to 1e300: no 0·∞).

Chromatic extinction (σt differs per channel in a scattering slab): path-level spectral MIS
with one hero channel per walk (the balance heuristic over the channels for the whole path, as
pbrt-v4's volumetric integrator): free flights sample the hero's rate and the walk keeps
per-channel density ratios r (mean 1), so the throughput is f_c/mean_c p_c (bounded by 3 f_c/p_c).
Depth densities recorded for MIS are channel means. A stochastic-pdf walk estimates the density
of the single-channel sampler of the shared hero (both walks of a query get the same hero).

Termination: unbiased Russian roulette on the throughput after vertex ``rr_start`` (survival
min(1, max β / threshold)), and a hard cap whose hits are counted (``capped``), never silent.
Random numbers: the lane's walk stream (``phase.rnd``).
"""
from __future__ import annotations

import math

from . import iface as ki
from . import phase as ph
from ..jit import inlined, kernel
from .table import (ABSORBING, EMPTY, H_CHROM, H_N, HEAD, M_ALB, M_DIR, M_GREY, M_KIND, M_PH,
                    M_TAU, MED0, MSTRIDE)

GRAZING = 1e-7          # |d_z| below this cannot cross a slab (Guo's double-precision epsilon)
BIG = 1e300             # clamp of the MIS coefficients
NONE, VALUE, PDF = 0, 1, 2
# Russian roulette (start vertex, threshold). Walks feeding the estimators (eval, pdf) use an
# aggressive setting: their connection cost grows with the square of the walk length while the
# variance barely changes (measured on the NumPy walks: Fig. 2 stack, 3× faster at +3 %
# variance). Walks that *are* the sample keep a mild one: their weight goes into the image.
RR_EVAL_START, RR_EVAL_THR = 2, 1.0
RR_SAMPLE_START, RR_SAMPLE_THR = 4, 0.25
RR_OFF = 1 << 62

F_KIND, F_LAYER, F_T, F_WIN, F_WOUT, F_THRU0, F_THRU1, F_PF, F_DELTA = 0, 1, 2, 3, 6, 9, 12, 15, 16
F_C1, F_C2, F_A, F_B, F_SIGIN, F_SIGOUT, F_GAMMA, F_QBG, F_REV, F_TERM = 17, 18, 19, 20, 21, 22, 23, 24, 25, 26
F_PR, F_DF, F_DR, F_P, F_Q = 27, 28, 29, 30, 31
NF = 32


@kernel(error_model="numpy")
def _inv(x):
    return 1.0 / x if x > 0.0 else 0.0


@kernel(error_model="numpy")
def _max3(a):
    return max(a[0], max(a[1], a[2]))


@kernel(error_model="numpy")
def flight(B, mo, s0, d, sig, prev_medium, approx, hero_pdf, hero, r, R):
    """A free flight from normalised depth s0 along d through the (non-empty) slab block ``mo``:
    a scattering depth inside it, or its boundary. Returns (scattered, new normalised depth,
    throughput factor RGB, gamma factor, new spectral ratios r, density of the event (per unit
    depth if scattered, else the probability of passing), reverse density of the previous
    vertex's depth (``prev_medium``: it was a medium vertex)). ``approx`` (approximate pdf) and
    absorbing slabs pass straight through (transmittance into the throughput, or its channel
    mean into gamma); ``hero_pdf``: a stochastic-pdf walk samples the hero channel alone."""
    inv = sig / abs(d[2])
    rate = (B[mo + M_TAU] * inv, B[mo + M_TAU + 1] * inv, B[mo + M_TAU + 2] * inv)
    grey = B[mo + M_GREY] > 0.0
    dmax = max(s0 if d[2] > 0.0 else 1.0 - s0, 0.0)
    one = (1.0, 1.0, 1.0)
    bound = 0.0 if d[2] > 0.0 else 1.0
    if approx or B[mo + M_KIND] == ABSORBING:
        if grey:
            e = math.exp(-rate[0] * dmax)
            e3 = (e, e, e)
        else:
            e3 = (math.exp(-rate[0] * dmax), math.exp(-rate[1] * dmax), math.exp(-rate[2] * dmax))
        if approx:
            return False, bound, one, (e3[0] + e3[1] + e3[2]) / 3.0, r, 1.0, 1.0
        return False, bound, e3, 1.0, r, 1.0, 1.0
    hero_flight = hero_pdf and not grey
    # Exponential steps as −log(1 − u): the stream's uniforms are multiples of 2⁻⁵³ in [0, 1),
    # so 1 − u is exact and log(1 − u) as accurate as log1p(−u), at about half the cost.
    if grey or hero_flight:
        rh = rate[hero] if hero_flight else rate[0]
        step = -math.log(1.0 - ph.rnd(R)) / rh if rh > 0.0 else math.inf
        sc = step < dmax
        if not sc:
            step = dmax
        ex = math.exp(-rh * step)
        fac = one
        if sc and not hero_flight:
            fac = (B[mo + M_ALB], B[mo + M_ALB + 1], B[mo + M_ALB + 2])
        dens = rh * ex if sc else ex
        drev = rh * ex if prev_medium else ex
    else:
        # Spectral MIS with the walk's hero channel (module docstring).
        rh = rate[hero]
        step = -math.log(1.0 - ph.rnd(R)) / rh if rh > 0.0 else math.inf
        sc = step < dmax
        if not sc:
            step = dmax
        e0 = math.exp(-rate[0] * step)
        e1 = math.exp(-rate[1] * step)
        e2 = math.exp(-rate[2] * step)
        q0, q1, q2 = rate[0] * e0, rate[1] * e1, rate[2] * e2
        if sc:
            p0, p1, p2 = q0, q1, q2
            f0, f1, f2 = B[mo + M_ALB] * q0, B[mo + M_ALB + 1] * q1, B[mo + M_ALB + 2] * q2
        else:
            p0, p1, p2 = e0, e1, e2
            f0, f1, f2 = e0, e1, e2
        n0, n1, n2 = r[0] * p0, r[1] * p1, r[2] * p2
        mean_r = (n0 + n1 + n2) / 3.0
        if mean_r > 0.0:
            im = 1.0 / mean_r
            fac = (f0 * im, f1 * im, f2 * im)
            r = (n0 * im, n1 * im, n2 * im)
        else:
            fac = (0.0, 0.0, 0.0)
            r = one
        dens = (p0 + p1 + p2) / 3.0
        drev = (q0 + q1 + q2) / 3.0 if prev_medium else (e0 + e1 + e2) / 3.0
    if sc:
        return True, (s0 - step if d[2] > 0.0 else s0 + step), fac, 1.0, r, dens, drev
    return False, bound, fac, 1.0, r, dens, drev


@kernel(error_model="numpy")
def transmittance(B, FT, k, d, t0, t1):
    """Transmittance in slab k from depth t0 to t1 along d (0 if d does not lead there; 1 over
    zero length)."""
    diff = t1 - t0
    if diff == 0.0:
        return (1.0, 1.0, 1.0)
    if not (diff * -d[2] > 0.0 and abs(d[2]) >= GRAZING):
        return (0.0, 0.0, 0.0)
    mo = MED0 + k * MSTRIDE
    if B[mo + M_KIND] == EMPTY:
        return (1.0, 1.0, 1.0)
    x = abs(diff) / abs(d[2])
    if B[mo + M_DIR] > 0.0:
        x *= ph.sigma_scale(B, mo + M_PH, FT, d)
    if B[mo + M_GREY] > 0.0:
        e = math.exp(-B[mo + M_TAU] * x)
        return (e, e, e)
    return (math.exp(-B[mo + M_TAU] * x), math.exp(-B[mo + M_TAU + 1] * x), math.exp(-B[mo + M_TAU + 2] * x))


@kernel(error_model="numpy")
def depth_density(B, FT, k, d, t0, t1, to_medium, hero):
    """Density with which a free flight in slab k along d from depth t0 produces depth t1: per
    unit depth if ``to_medium`` (a scattering vertex), else the probability of reaching the
    boundary t1; the channel mean, or channel ``hero`` ≥ 0 alone (a stochastic-pdf walk). 1 for
    slabs crossed without sampling (empty, absorbing)."""
    mo = MED0 + k * MSTRIDE
    if B[mo + M_KIND] != 2.0 or not abs(d[2]) >= GRAZING:
        return 1.0 if B[mo + M_KIND] != 2.0 else 0.0
    inv = 1.0 / abs(d[2])
    if B[mo + M_DIR] > 0.0:
        inv *= ph.sigma_scale(B, mo + M_PH, FT, d)
    x = abs(t1 - t0)
    out = 0.0
    for c in range(3):
        if hero >= 0 and B[mo + M_GREY] <= 0.0 and c != hero:
            continue
        rc = B[mo + M_TAU + c] * inv
        e = math.exp(-rc * x)
        out += rc * e if to_medium else e
    if hero >= 0 and B[mo + M_GREY] <= 0.0:
        return out
    return out / 3.0


@inlined
def run(B, FT, w0, W, slot, R, purpose, approx, rr_start, rr_thr, cap, hero):
    """``walk`` with every flag turned into a runtime value. Numba types constant arguments as
    literals and compiles a specialisation of the callee per combination of them (the walk was
    compiled four times); ``x + 0`` of a variable, ``b == True``, ``f * 1.0`` are plain int64,
    bool and float64. Callers use this (it is inlined, the walk itself is not)."""
    return walk(B, FT, w0, W, slot + 0, R, purpose + 0, approx == True, rr_start + 0,  # noqa: E712
                rr_thr * 1.0, cap + 0, hero + 0)


@kernel(error_model="numpy")
def walk(B, FT, w0, W, slot, R, purpose, approx, rr_start, rr_thr, cap, hero):
    """Walk from direction ``w0`` (pointing away from the surface): enter at the top if w0_z > 0,
    else at the bottom. ``approx``: media do not scatter (crossing a slab multiplies ``gamma`` by
    its pass probability), for the approximate pdf. ``hero``: the hero channel (−1: draw one
    where needed). Returns (vertices, exit direction, exit throughput (0 if the walk did not
    leave the stack), every vertex a delta sample, capped, hero)."""
    zero = (0.0, 0.0, 0.0)
    if w0[2] == 0.0:
        return 0, zero, zero, False, 0, hero
    N = int(B[H_N])
    record = purpose != NONE
    chromatic = B[H_CHROM] > 0.0 and not approx
    hero_pdf = chromatic and purpose == PDF
    if chromatic and hero < 0:
        hero = min(int(ph.rnd(R) * 3.0), 2)
    layer = 0 if w0[2] > 0.0 else N - 1
    is_if = True
    t = float(layer)
    d = (-w0[0], -w0[1], -w0[2])
    beta = (1.0, 1.0, 1.0)
    gamma = 1.0
    all_delta = True
    dens_f = 1.0
    dens_r = 1.0
    own_p = 0.0
    b1_p = 0.0
    ipf_p = 0.0
    qb_p = 1.0
    pr_p = 0.0
    sig = 1.0
    r0 = 1.0
    r1 = 1.0
    r2 = 1.0
    i = 1
    while True:
        w_in = (-d[0], -d[1], -d[2])
        if is_if:
            o = HEAD + layer * ki.STRIDE
            if B[o + ki.IF_FRAMED] > 0.0:
                a = ki.arrival(B, o, w_in)
                beta = (beta[0] * a, beta[1] * a, beta[2] * a)
            u0 = ph.rnd(R)
            u1 = ph.rnd(R)
            u2 = ph.rnd(R)
            d_out, wgt, pf, pr, delta = ki.sample(B, o, w_in, u0, u1, u2, record == True)  # noqa: E712
            sig_new = sig
        else:
            mo = MED0 + layer * MSTRIDE
            d_out, w1, pf, pr, s_out, _ = ph.sample(B, mo + M_PH, FT, d, sig, R, cap * 0 + ph.MAX_CANDIDATES)
            wgt = (w1, w1, w1)
            delta = False
            sig_new = s_out if B[mo + M_DIR] > 0.0 else sig
        thru1 = (beta[0] * wgt[0], beta[1] * wgt[1], beta[2] * wgt[2])
        if record:
            first = i == 1
            inv_dens = 0.0 if first else _inv(dens_f)
            P = dens_r * b1_p
            a = (own_p + P) * ipf_p
            own = 0.0 if delta else 1.0
            ipf = _inv(pf)
            b1 = inv_dens * (own + pr * a)
            qb = 1.0 if first else inv_dens * dens_r * pr_p * qb_p * ipf_p
            v = W[slot, i - 1]
            v[F_KIND] = 1.0 if is_if else 0.0
            v[F_LAYER] = layer
            v[F_T] = t
            for j in range(3):
                v[F_WIN + j] = w_in[j]
                v[F_WOUT + j] = d_out[j]
                v[F_THRU0 + j] = beta[j]
                v[F_THRU1 + j] = thru1[j]
            v[F_PF] = pf
            v[F_DELTA] = 1.0 if delta else 0.0
            v[F_C1] = min(inv_dens, BIG)
            v[F_C2] = min(inv_dens * a, BIG)
            v[F_A] = min(ipf * own, BIG)
            v[F_B] = min(ipf * b1, BIG)
            v[F_SIGIN] = sig
            v[F_SIGOUT] = math.nan if is_if else sig_new
            v[F_GAMMA] = gamma
            v[F_QBG] = qb * gamma
            v[F_REV] = ipf * pr * qb * gamma
            v[F_TERM] = math.nan
            v[F_PR] = pr
            v[F_DF] = dens_f
            v[F_DR] = dens_r
            v[F_P] = P
            v[F_Q] = 0.0 if first else dens_r * pr_p * qb_p
            own_p = own
            b1_p = b1
            ipf_p = ipf
            qb_p = qb
            pr_p = pr
        beta = thru1
        all_delta = all_delta and delta and is_if
        sig = sig_new
        up = d_out[2] > 0.0
        if is_if and ((up and layer == 0) or (not up and layer == N - 1)):
            return i, d_out, beta, all_delta, 0, hero
        bmax = _max3(beta)
        alive = abs(d_out[2]) >= GRAZING and bmax > 0.0
        if alive and i >= rr_start and not approx:
            q = min(1.0, bmax / rr_thr)
            if ph.rnd(R) < q and q > 1e-300:
                iq = 1.0 / q
                beta = (beta[0] * iq, beta[1] * iq, beta[2] * iq)
                gamma *= iq
            else:
                alive = False
        if not alive:
            return i, d_out, zero, False, 0, hero
        if i >= cap:
            return i, d_out, zero, False, 1, hero
        # ------------------------------------------------------------ free flight
        slab = (layer - 1 if up else layer) if is_if else layer
        prev_medium = not is_if
        d = d_out
        layer = slab if up else slab + 1
        is_if = True
        t_new = float(layer)
        dens_f = 1.0
        dens_r = 1.0
        mo = MED0 + slab * MSTRIDE
        if B[mo + M_KIND] != EMPTY:
            sg = 1.0
            if B[mo + M_DIR] > 0.0:
                # The extinction scale of the direction: the phase sampler's after a medium
                # vertex of this slab, computed on entering the slab from an interface.
                if not prev_medium:
                    sig = ph.sigma_scale(B, mo + M_PH, FT, d)
                    if record:
                        W[slot, i - 1, F_SIGOUT] = sig
                sg = sig
            sc, s1, fac, gfac, r, dens, drev = flight(B, mo, t - slab, d, sg, prev_medium, approx,
                                                     hero_pdf, hero, (r0, r1, r2), R)
            r0, r1, r2 = r
            beta = (beta[0] * fac[0], beta[1] * fac[1], beta[2] * fac[2])
            gamma *= gfac
            if sc:
                t_new = slab + s1
                is_if = False
                layer = slab
            dens_f = dens
            dens_r = drev
        t = t_new
        if not _max3(beta) > 0.0:
            return i, d, zero, False, 0, hero
        i += 1
