"""Bidirectional estimator of the layered BSDF and of its sampling pdf (Guo et al. 2018 §4.2.2, §4.3).

A walk L from wi and a walk R from wo (both importance transport, walk.py) are connected vertex
to vertex inside a slab. A full path x_1 … x_n (x_1 on the entry interface, x_n on the exit one)
has 2(n − 1) strategies: the depth split s (L makes depths z_1..z_s, R the rest) and whether the
connecting direction d_s was sampled by L (u = 0: L's sampled direction at L_s, R's vertex is
evaluated) or by R (u = 1: R's sampled direction at R_{n−s}, L's vertex is evaluated). Strategy
(s, u) evaluates vertex x_{s+1−u}; it is impossible if that vertex was sampled from a delta lobe.

MIS: the balance heuristic over all strategies, in O(1) per connection from the running sums P
and products Q that the walks accumulate (walk.py) plus the local connection densities. Writing
π for a strategy's path density, consecutive strategies differ by one ratio: a direction moved
from one walk to the other (forward/reverse sampling pdfs) or a depth moved (free-flight densities:
per unit depth for a medium vertex, the pass probability for an interface). Delta lobes use the
placeholder density 1 on both sides (consistent for every strategy of a path, so the weights still
sum to one; see pbrt's BDPT for the same device).

Value of a connection (η² bookkeeping, digest §6.2): R's subpath was sampled with importance
transport starting from wo, so its vertices stand for the adjoint flow; the generalised
reciprocity f(x→y)/η_y² = f(y→x)/η_x² of every interface telescopes along R to (η_wo-side/η_k)²
for a connection in slab k. Segment cosines follow the paper's rule
(|cos|^([x iface] + [y iface] − 1)): the walk weights and the evaluated interface BSDF each carry
one |cos d| of the connecting direction, so each connection divides by |cos d| once.

The pdf estimate (eqs. 19–20 of the paper): the same paths with the integrand replaced by the
product of the forward sampler's direction pdfs and depth densities. L *is* the sampler, so its
weight is 1 (times ``gamma``: roulette compensation and, in the approximate mode, slab pass
probabilities); with the balance heuristic a connection contributes UP/Σ where UP is the product
of forward/reverse ratios from the strategy to the all-L one — Q (walk.py) times local ratios.
"""
from __future__ import annotations

import numpy as np

from .stack import GRAZING, BoundStack
from .walk import Records

MAX_PAIRS = 1 << 19  # connections processed at once (memory bound)


def safe_div(a, b):
    ok = b > 0
    return np.where(ok, a / np.where(ok, b, 1.0), 0.0)


def eval_vertex(stack: BoundStack, rec, rows: np.ndarray, w: np.ndarray,
                rng: np.random.Generator, need_rev: bool = True):
    """Vertex function of records ``rows`` (of a Records or ConnView) for the outgoing direction
    ``w`` ((3, m), pointing away from the vertex): interface f(w_in → w)·|cos w| (importance) or
    phase p(−w_in → w); plus the forward density of w given w_in and the reverse density of w_in
    given w."""
    return eval_at(stack, rec.kind[rows], rec.layer[rows], rec.lane[rows], rec.w_in[:, rows], w,
                   rng, need_rev)


def eval_at(stack: BoundStack, kind, layer, lane, w_in, w, rng, need_rev: bool = True,
            pdf_only: bool = False):
    m = lane.size
    N = stack.N
    if np.all(kind == 1):
        groups = [(1, l, None if N == 1 else np.flatnonzero(layer == l)) for l in range(N)]
    else:
        groups = [(1, l, np.flatnonzero((kind == 1) & (layer == l))) for l in range(N)]
        groups += [(0, k, np.flatnonzero((kind == 0) & (layer == k))) for k in range(N - 1)]
    groups = [g for g in groups if g[2] is None or g[2].size]
    if len(groups) == 1:
        return _eval_group(stack, groups[0][0], groups[0][1], lane, w_in, w, rng, need_rev, pdf_only)
    val = None if pdf_only else np.zeros((3, m))
    pf = np.zeros(m)
    pr = np.zeros(m) if need_rev else None
    for is_if, l, pos in groups:
        v, f, r = _eval_group(stack, is_if, l, lane[pos], w_in[:, pos], w[:, pos], rng, need_rev,
                              pdf_only)
        if not pdf_only:
            val[:, pos] = v
        pf[pos] = f
        if need_rev:
            pr[pos] = r
    return val, pf, pr


def _eval_group(stack, is_if, l, lane, w_in, w, rng, need_rev, pdf_only=False):
    if is_if:
        ker = stack.kernels[l]
        if ker.delta_only:
            m = lane.size
            return np.zeros((3, m)), np.zeros(m), np.zeros(m)
        if ker.generic:
            return ker.take(lane).eval(w_in, w, rng, need_rev)
        return ker.take(lane).eval(w_in, w, rng, need_rev, pdf_only)
    ph = stack.slabs[l].phase.take(lane)
    d_in, d_out = (-w_in).T, w.T
    p = ph.eval(d_in, d_out)
    pr = ph.pdf(-d_out, -d_in) if need_rev else None
    return np.broadcast_to(p, (3, p.size)), p, pr


def _pairs(L, R, lanes: np.ndarray):
    """All (L, R) pairs of the given lanes, as positions in the lane-major views."""
    cL, cR = L.count[lanes], R.count[lanes]
    npair = cL * cR
    total = int(npair.sum())
    if total == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e, e
    pl = np.repeat(lanes, npair)
    start = np.repeat(np.cumsum(npair) - npair, npair)
    q = np.arange(total) - start
    cRp = R.count[pl]
    iL = L.offset[pl] + q // cRp
    iR = R.offset[pl] + q % cRp
    return pl, iL, iR


def _lane_batches(L, R):
    npair = L.count * R.count
    csum = np.cumsum(npair)
    lanes = np.arange(L.n)
    if csum.size == 0 or csum[-1] <= MAX_PAIRS:
        return [lanes]
    cut = np.searchsorted(csum, np.arange(MAX_PAIRS, csum[-1], MAX_PAIRS), side="right")
    return [b for b in np.split(lanes, cut) if b.size]


def bidirectional(stack: BoundStack, wo: np.ndarray, L: Records, R: Records, rng,
                  pdf_mode: bool = False, approx: bool = False, nmax: np.ndarray | None = None):
    """Sum over all connections per lane: (3, n) f·|cos θo| / |cos θo| (i.e. without the final
    cosine, without the single-interface term and before any transport-mode factor) or, with
    ``pdf_mode``, (n,) the pdf estimate. ``wo`` is (3, n). ``nmax`` (per lane) keeps only paths
    of at most that many vertices (approximate pdf)."""
    n = L.n
    Lv, Rv = L.view(), R.view()
    out = np.zeros(n) if pdf_mode else np.zeros((3, n))
    N = stack.N
    exit_top = wo[2] > 0
    for lanes in _lane_batches(Lv, Rv):
        pl, iL, iR = _pairs(Lv, Rv, lanes)
        if not pl.size:
            continue
        loL, loR, hiL, hiR = Lv.lo[iL], Rv.lo[iR], Lv.hi[iL], Rv.hi[iR]
        slab = np.maximum(loL, loR)
        # Same slab (or the slab between two adjacent interfaces), not the same interface.
        ok = (slab <= np.minimum(hiL, hiR)) & (slab >= 0) & (slab <= N - 2)
        ok &= ~((loL == loR) & (hiL == hiR) & (hiL > loL))
        if nmax is not None:
            ok &= (Lv.k[iL] + Rv.k[iR]) <= nmax[pl]
        dt = Rv.t[iR] - Lv.t[iL]
        for u in (0, 1):
            if u == 0:
                cz, src = Lv.w_out[2, iL], Lv.live_out[iL]
            else:
                cz, src = -Rv.w_out[2, iR], Rv.live_out[iR]
            sel = np.flatnonzero(ok & src & (-cz * dt > 0) & (np.abs(cz) >= GRAZING))
            if not sel.size:
                continue
            contrib = _connect(stack, Lv, Rv, iL[sel], iR[sel], pl[sel], slab[sel], u,
                               exit_top, rng, pdf_mode, approx)
            if pdf_mode:
                out += np.bincount(pl[sel], contrib, minlength=n)
            else:
                for ch in range(3):
                    out[ch] += np.bincount(pl[sel], contrib[ch], minlength=n)
    return out


def _connect(stack, L, R, iL, iR, pl, slab, u, exit_top, rng, pdf_mode, approx):
    m = iL.size
    tL, tR = L.t[iL], R.t[iR]
    kL, kR = L.kind[iL], R.kind[iR]
    if u == 0:
        # L sampled c; evaluate R's vertex towards L (direction −c, pointing away from R_j).
        c = np.take(L.w_out, iL, axis=1)
        v, pf, pr = eval_at(stack, kR, R.layer[iR], pl, np.take(R.w_in, iR, axis=1), -c, rng,
                            pdf_only=pdf_mode)
    else:
        c = -np.take(R.w_out, iR, axis=1)
        v, pf, pr = eval_at(stack, kL, L.layer[iL], pl, np.take(L.w_in, iL, axis=1), c, rng,
                            pdf_only=pdf_mode)
    T = np.ones(m) if pdf_mode else np.ones((3, m))
    pass_p = np.ones(m)
    dens_to_R = np.ones(m)
    dens_to_L = np.ones(m)
    for k in range(stack.N - 1):
        if stack.kinds[k] == 0 and not approx:
            continue  # empty slab: transmittance and densities 1
        whole = stack.N == 2
        pos = None if whole else np.flatnonzero(slab == k)
        if pos is not None and not pos.size:
            continue
        sl = (lambda a: a) if whole else (lambda a: a[..., pos])
        lanes, ck, t0, t1 = sl(pl), sl(c), sl(tL), sl(tR)
        if not pdf_mode:
            Tk = stack.transmittance(k, lanes, ck, t0, t1)
            if whole:
                T = T * Tk
            else:
                T[:, pos] = Tk
        elif approx:
            pp = stack.pass_probability(k, lanes, ck, t0, t1)
            if whole:
                pass_p = pp
            else:
                pass_p[pos] = pp
        if not approx and stack.kinds[k] == 2:
            ops = stack.slabs[k].take(lanes)
            a = ops.depth_pdf(ck, t0 - k, t1 - k, sl(kR) == 0)
            b = ops.depth_pdf(-ck, t1 - k, t0 - k, sl(kL) == 0)
            if whole:
                dens_to_R, dens_to_L = a, b
            else:
                dens_to_R[pos], dens_to_L[pos] = a, b
    if u == 0:
        # L sampled; R_j evaluated: pf = R_j's density towards L_i, pr = of R's own incoming.
        S_L = pf * L.inv_pf[iL] * (L.own[iL] + dens_to_L * L.b1[iL])
        S_R = dens_to_R * R.inv_dens[iR] * (1.0 + pr * R.a[iR])
    else:
        S_L = dens_to_L * L.inv_dens[iL] * (1.0 + pr * L.a[iL])
        S_R = pf * R.inv_pf[iR] * (R.own[iR] + dens_to_R * R.b1[iR])
    w_mis = 1.0 / (1.0 + S_L + S_R)
    if pdf_mode:
        qb = R.qb[iR]
        if u == 0:
            up = dens_to_R * pr * qb
        else:
            up = pf * R.inv_pf[iR] * dens_to_R * R.pdf_rev[iR] * qb
        return up * L.gamma[iL] * R.gamma[iR] * w_mis * pass_p
    scale = w_mis * stack.eta_corr(slab, exit_top[pl]) / np.abs(c[2])
    if u == 0:
        val = np.take(L.thru1, iL, axis=1) * np.take(R.thru0, iR, axis=1)
    else:
        val = np.take(L.thru0, iL, axis=1) * np.take(R.thru1, iR, axis=1)
    return val * v * T * scale
