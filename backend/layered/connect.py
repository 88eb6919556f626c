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


def eval_vertex(stack: BoundStack, rec: Records, rows: np.ndarray, w: np.ndarray,
                rng: np.random.Generator, need_rev: bool = True):
    """Vertex function of records ``rows`` for the outgoing direction ``w`` ((3, m), pointing
    away from the vertex): interface f(w_in → w)·|cos w| (importance) or phase p(−w_in → w);
    plus the forward density of w given w_in and the reverse density of w_in given w."""
    m = rows.size
    kind = rec.kind[rows]
    layer = rec.layer[rows]
    lane = rec.lane[rows]
    w_in = rec.w_in[:, rows]
    N = stack.N
    groups = [(1, l, np.flatnonzero((kind == 1) & (layer == l))) for l in range(N)]
    if not np.all(kind == 1):
        groups += [(0, k, np.flatnonzero((kind == 0) & (layer == k))) for k in range(N - 1)]
    groups = [g for g in groups if g[2].size]
    if len(groups) == 1:
        return _eval_group(stack, groups[0][0], groups[0][1], lane, w_in, w, rng, need_rev)
    val = np.zeros((3, m))
    pf = np.zeros(m)
    pr = np.zeros(m) if need_rev else None
    for is_if, l, pos in groups:
        v, f, r = _eval_group(stack, is_if, l, lane[pos], w_in[:, pos], w[:, pos], rng, need_rev)
        val[:, pos] = v
        pf[pos] = f
        if need_rev:
            pr[pos] = r
    return val, pf, pr


def _eval_group(stack, is_if, l, lane, w_in, w, rng, need_rev):
    if is_if:
        ker = stack.kernels[l]
        if ker.delta_only:
            m = lane.size
            return np.zeros((3, m)), np.zeros(m), np.zeros(m)
        return ker.take(lane).eval(w_in, w, rng, need_rev)
    ph = stack.slabs[l].phase.take(lane)
    d_in, d_out = (-w_in).T, w.T
    p = ph.eval(d_in, d_out)
    pr = ph.pdf(-d_out, -d_in) if need_rev else None
    return np.broadcast_to(p, (3, p.size)), p, pr


def _A(X: Records, rows, valid, pdfrev, dens_in):
    """Sum of π(strategy)/π(current) over the strategies that move depths/directions of X's
    subpath to the other walk, given the connection-dependent reverse density at X_i."""
    inner = safe_div(dens_in, X.dens_fwd[rows]) * (
        valid + safe_div(pdfrev, X.pdf_fwd_prev[rows]) * ((~X.delta_prev[rows]) + X.P[rows]))
    return np.where(X.k[rows] == 1, 0.0, inner)


def _S_evaluated(X: Records, rows, pdfrev_conn, dens_in):
    """X's side of the MIS sum when X's vertex is the evaluated one."""
    return _A(X, rows, 1.0, pdfrev_conn, dens_in)


def _S_sampled(X: Records, rows, pdf_other, dens_in):
    """X's side of the MIS sum when X sampled the connecting direction itself."""
    own = ~X.delta[rows]
    return safe_div(pdf_other, X.pdf_fwd[rows]) * (own + _A(X, rows, own, X.pdf_rev[rows], dens_in))


def _B(X: Records, rows, pdfrev, dens_in):
    """Product of forward/reverse ratios from the strategy to the all-L one along X (= R)."""
    inner = safe_div(dens_in, X.dens_fwd[rows]) * safe_div(pdfrev, X.pdf_fwd_prev[rows]) * X.Q[rows]
    return np.where(X.k[rows] == 1, pdfrev * dens_in, inner)


def _pairs(L: Records, R: Records, lanes: np.ndarray):
    """All (L row, R row) pairs of the given lanes."""
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
    iL = L.perm[L.offset[pl] + q // cRp]
    iR = R.perm[R.offset[pl] + q % cRp]
    return pl, iL, iR


def _lane_batches(L: Records, R: Records):
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
    out = np.zeros(n) if pdf_mode else np.zeros((3, n))
    N = stack.N
    exit_top = wo[2] > 0
    for lanes in _lane_batches(L, R):
        pl, iL, iR = _pairs(L, R, lanes)
        if not pl.size:
            continue
        kL, kR = L.kind[iL], R.kind[iR]
        yL, yR = L.layer[iL], R.layer[iR]
        loL = np.where(kL == 1, yL - 1, yL)
        loR = np.where(kR == 1, yR - 1, yR)
        slab = np.maximum(loL, loR)
        ok = (slab <= np.minimum(yL, yR)) & (slab >= 0) & (slab <= N - 2)
        ok &= ~((kL == 1) & (kR == 1) & (yL == yR))
        if nmax is not None:
            ok &= (L.k[iL] + R.k[iR]) <= nmax[pl]
        dt = R.t[iR] - L.t[iL]
        for u in (0, 1):
            if u == 0:
                cz = L.w_out[2, iL]
                src = L.pdf_fwd[iL] > 0 if pdf_mode else L.thru1[:, iL].max(axis=0) > 0
            else:
                cz = -R.w_out[2, iR]
                src = R.pdf_fwd[iR] > 0 if pdf_mode else R.thru1[:, iR].max(axis=0) > 0
            sel = np.flatnonzero(ok & src & (-cz * dt > 0) & (np.abs(cz) >= GRAZING))
            if not sel.size:
                continue
            c = L.w_out[:, iL[sel]] if u == 0 else -R.w_out[:, iR[sel]]
            contrib = _connect(stack, L, R, iL[sel], iR[sel], pl[sel], c, slab[sel], u,
                               exit_top, rng, pdf_mode, approx)
            if pdf_mode:
                out += np.bincount(pl[sel], contrib, minlength=n)
            else:
                for ch in range(3):
                    out[ch] += np.bincount(pl[sel], contrib[ch], minlength=n)
    return out


def _connect(stack, L, R, iL, iR, pl, c, slab, u, exit_top, rng, pdf_mode, approx):
    m = iL.size
    tL, tR = L.t[iL], R.t[iR]
    if u == 0:
        # L sampled c; evaluate R's vertex towards L (direction −c, pointing away from R_j).
        v, pf, pr = eval_vertex(stack, R, iR, -c, rng)
    else:
        v, pf, pr = eval_vertex(stack, L, iL, c, rng)
    T = np.ones(m) if pdf_mode else np.ones((3, m))
    pass_p = np.ones(m)
    dens_to_R = np.ones(m)
    dens_to_L = np.ones(m)
    toR_med = R.kind[iR] == 0
    toL_med = L.kind[iL] == 0
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
            a = ops.depth_pdf(ck, t0 - k, t1 - k, sl(toR_med))
            b = ops.depth_pdf(-ck, t1 - k, t0 - k, sl(toL_med))
            if whole:
                dens_to_R, dens_to_L = a, b
            else:
                dens_to_R[pos], dens_to_L[pos] = a, b
    if u == 0:
        S_L = _S_sampled(L, iL, pf, dens_to_L)       # pf = pdf at R_j of sampling towards L_i
        S_R = _S_evaluated(R, iR, pr, dens_to_R)     # pr = pdf at R_j of R's own incoming
    else:
        S_L = _S_evaluated(L, iL, pr, dens_to_L)
        S_R = _S_sampled(R, iR, pf, dens_to_R)
    w_mis = 1.0 / (1.0 + S_L + S_R)
    if pdf_mode:
        if u == 0:
            up = _B(R, iR, pr, dens_to_R)
        else:
            up = safe_div(pf, R.pdf_fwd[iR]) * _B(R, iR, R.pdf_rev[iR], dens_to_R)
        return up * L.gamma[iL] * R.gamma[iR] * w_mis * pass_p
    scale = w_mis * stack.eta_corr(slab, exit_top[pl]) / np.abs(c[2])
    if u == 0:
        val = L.thru1[:, iL] * R.thru0[:, iR]
    else:
        val = L.thru0[:, iL] * R.thru1[:, iR]
    return val * v * T * scale
