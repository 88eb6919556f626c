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

Engine. A connection needs the evaluated vertex's function and densities and, for the MIS
weight, a handful of coefficients of both vertices. Everything that depends on one vertex only
is computed once per vertex (:class:`Side`): the MIS recurrences folded into five coefficients,
and for a vertex whose sampled direction c is the connecting direction ("source") the slab it
enters, the extinction rate along c and, towards an interface, the whole transmittance and both
depth densities (the depth difference to an interface is known per source). Sources are grouped
by (slab, up/down); the vertices they can be joined to ("targets": the other walk's vertices on
the interface ahead, or in the same slab's medium, on the right side) are grouped by interface /
medium and stored lane-major, so the candidates of a source are one contiguous range and every
batch evaluates a single kernel or phase function without masks. Connections are processed in
blocks of ``BLOCK`` so that the temporaries stay in the L2 cache (measured on the project VM:
~0.5 ns per element operation at 16–32 K elements, 3 ns at 512 K, 13 ns at 2.4 M). Per-source
factors (throughput, |cos|, η², transmittance to an interface) multiply the per-source sums.

Per-vertex MIS coefficients are clamped to 1e300 so that 0 · ∞ cannot occur in a weight.
"""

from __future__ import annotations

import numpy as np

from .stack import ABSORBING, EMPTY, GRAZING, SCATTERING, BoundStack
from .walk import Records

BLOCK = 16384   # connections per block (cache-sized temporaries, see the module docstring)
BIG = 1e300     # clamp of the per-vertex MIS coefficients (no 0·∞ in the weights)


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


def _t(x, idx):
    """x[..., idx]: np.take along the last axis is ~3× faster than fancy indexing of (3, m)."""
    return np.take(x, idx, axis=-1)


def _inv(x):
    ok = x > 0
    return np.where(ok, 1.0 / np.where(ok, x, 1.0), 0.0)


class _Group:
    """Targets of one kind (vertices on interface l, or medium vertices of slab k), lane-major."""


class _Bucket:
    """Sources whose sampled direction enters slab s going up or down."""


def _slices(code, nbins):
    """Stable order of ``code`` (small non-negative ints; radix sort) and the slice of each bin."""
    order = np.argsort(code.astype(np.int16), kind="stable")
    edges = np.searchsorted(code[order], np.arange(nbins + 1), side="left")
    return order, edges


class Side:
    """One walk's vertices of the record lanes [r0, r1), prepared for connections (see the
    module docstring). Lanes are numbered from 0 inside the block; block lane j is the stack's
    lane l0 + j.

    MIS coefficients (recorded by the walk, walk.py): as the evaluated vertex ("target", with
    density dens_in of reaching it along the connection and reverse density pr of its own
    incoming direction) a vertex adds S = dens_in·(c1 + pr·c2) to the weight's denominator; as
    the sampling vertex ("source", the target's density pf of the connecting direction, dens_out
    the density of reaching the source back) S = pf·(A + dens_out·B)."""

    def __init__(self, stack: BoundStack, rec: Records, r0: int, r1: int, l0: int, pdf_mode: bool):
        N = stack.N
        n = r1 - r0
        self.n = n
        idx = rec.perm[rec.bounds[r0]:rec.bounds[r1]]   # the block's vertices, lane-major
        # Fields read only as targets or only as sources are gathered once, straight from the
        # records through the composed index (idx[order]), not via a lane-major copy.
        lane = rec.lane[idx] - r0
        kind, layer, t, k = rec.kind[idx], rec.layer[idx], rec.t[idx], rec.k[idx]
        is_if = kind == 1
        # ------------------------------------------------------------ targets
        group = np.where(is_if, layer, N + layer)
        order, edges = _slices(group, 2 * N - 1)
        self.targets = {}
        it = idx[order]
        tl, tt, tk, tw = lane[order], t[order], k[order], _t(rec.w_in, it)
        c1, c2 = rec.c1[it], rec.c2[it]
        if pdf_mode:
            tg, tq = rec.gamma[it], rec.qbg[it]
        else:
            t0 = _t(rec.thru0, it)
        # The walk's extinction scales σ(w_in) of medium vertices (directional phases).
        tsig = rec.sig_in[it] if hasattr(rec, "sig_in") else None
        for g in range(2 * N - 1):
            e0, e1 = int(edges[g]), int(edges[g + 1])
            if e1 <= e0:
                continue
            if g < N and stack.kernels[g].delta_only:
                continue  # a delta lobe cannot be evaluated: no strategy connects there
            G = _Group()
            G.lane, G.t, G.k, G.w_in = tl[e0:e1], tt[e0:e1], tk[e0:e1], tw[:, e0:e1]
            G.c1, G.c2 = c1[e0:e1], c2[e0:e1]
            if pdf_mode:
                G.gamma, G.qbg = tg[e0:e1], tq[e0:e1]
            else:
                G.thru0 = t0[:, e0:e1]
            G.count = np.bincount(G.lane, minlength=n)
            G.start = np.cumsum(G.count) - G.count
            G.sig = G.mt = None
            if g < N and not stack.kernels[g].generic:
                G.mt = stack.kernels[g].take(G.lane + l0).mask_terms(G.w_in)
            if g >= N and stack.slabs[g - N].directional:
                if tsig is not None:
                    G.sig = tsig[e0:e1]
                else:
                    G.sig = stack.slabs[g - N].phase.take(G.lane + l0).sigma3(G.w_in)
            self.targets[g] = G
        # ------------------------------------------------------------ sources
        wz = rec.w_out[2][idx]
        up = wz > 0
        slab = np.where(is_if, np.where(up, layer - 1, layer), layer)
        if pdf_mode:
            live = rec.pdf_fwd[idx] > 0
        else:
            th = _t(rec.thru1, idx)
            live = np.maximum(np.maximum(th[0], th[1]), th[2]) > 0
        ok = live & (np.abs(wz) >= GRAZING) & (slab >= 0) & (slab <= N - 2)
        nb = 2 * (N - 1)
        code = np.where(ok, 2 * slab + up, nb)
        order, edges = _slices(code, nb)
        e_end = int(edges[nb])
        order = order[:e_end]
        i_s = idx[order]
        sc = _t(rec.w_out, i_s)
        sl, st, sk = lane[order], t[order], k[order]
        smed = ~is_if[order]
        sA, sB = rec.A[i_s], rec.B[i_s]
        ssig = rec.sig_out[i_s] if hasattr(rec, "sig_out") else None
        if pdf_mode:
            sg, srev = rec.gamma[i_s], rec.rev[i_s]
        else:
            s1 = _t(rec.thru1, i_s)
        self.sources = {}
        for b in range(nb):
            e0, e1 = int(edges[b]), int(edges[b + 1])
            if e1 <= e0:
                continue
            B = _Bucket()
            B.lane, B.t, B.k, B.c, B.medium = sl[e0:e1], st[e0:e1], sk[e0:e1], sc[:, e0:e1], smed[e0:e1]
            B.A, B.B = sA[e0:e1], sB[e0:e1]
            B.sig = None if ssig is None else ssig[e0:e1]   # σ(c), valid at medium sources
            if pdf_mode:
                B.gamma, B.rev = sg[e0:e1], srev[e0:e1]
            else:
                B.thru1 = s1[:, e0:e1]
            self.sources[(b // 2, bool(b % 2))] = B


LANE_BLOCK = 4096  # lanes prepared and connected together (per-vertex arrays stay cache-sized)


def bidirectional(stack: BoundStack, wo: np.ndarray, L: Records, R: Records, rng,
                  pdf_mode: bool = False, approx: bool = False, nmax: np.ndarray | None = None,
                  L_off: int = 0, R_off: int = 0, hero: np.ndarray | None = None):
    """Sum over all connections per lane: (3, n) f·|cos θo| / |cos θo| (i.e. without the final
    cosine, without the single-interface term and before any transport-mode factor) or, with
    ``pdf_mode``, (n,) the pdf estimate. ``wo`` is (3, n), n = stack.n; lane j's two walks are
    lane L_off + j of L and lane R_off + j of R (one joint walk may hold both: L is R). ``nmax``
    (per lane) keeps only paths of at most that many vertices (approximate pdf). ``hero`` (n,):
    a stochastic pdf's shared hero channel of both walks (walk.walk), whose single-channel depth
    densities the connections then use in chromatic media."""
    n = wo.shape[1]
    out = np.zeros(n) if pdf_mode else np.zeros((3, n))
    exit_top = wo[2] > 0
    for l0 in range(0, n, LANE_BLOCK):
        l1 = min(n, l0 + LANE_BLOCK)
        Ls = Side(stack, L, L_off + l0, L_off + l1, l0, pdf_mode)
        Rs = Side(stack, R, R_off + l0, R_off + l1, l0, pdf_mode)
        o = out[..., l0:l1]
        nm = None if nmax is None else nmax[l0:l1]
        for u, src, tgt in ((0, Ls, Rs), (1, Rs, Ls)):
            _directed(stack, src, tgt, u, exit_top[l0:l1], l0, rng, pdf_mode, approx, nm, o,
                      None if hero is None else hero[l0:l1])
    return out


def _slab_terms(stack, s, B, ad_if, l0, pdf_mode, approx, hero=None):
    """Per source of bucket B in slab s: the extinction rate along its direction c (None for an
    empty slab; (m,) grey or (3, m)), sigma_scale(c) for a directional phase, and towards the
    interface ahead (depth distance ``ad_if``): transmittance (per-source factor), the depth
    densities of reaching the interface (dens_t) and of reaching the source back (dens_s)."""
    m = B.lane.size
    kind = stack.kinds[s]
    az = np.abs(B.c[2])
    one = np.ones(m)
    if kind == EMPTY:
        return None, None, 1.0, one, one
    ops = stack.slabs[s].take(B.lane + l0)
    sig = None
    inv = 1.0 / az
    if ops.directional:
        if B.sig is None:
            sig = ops.phase.sigma3(B.c)
        else:
            # Medium sources: the phase sampler's σ(c) (walk records); interface sources
            # entering the slab: computed here.
            sig = B.sig
            fresh = np.flatnonzero(~B.medium)
            if fresh.size:
                sig = sig.copy()
                sig[fresh] = stack.slabs[s].phase.take(B.lane[fresh] + l0).sigma3(_t(B.c, fresh))
        inv = inv * sig
    rate = ops.tau[0] * inv if ops.grey else ops.tau * inv
    if hero is not None and not ops.grey and kind == SCATTERING:
        rate = np.take_along_axis(rate, hero[B.lane][None, :], axis=0)[0]
    e = np.exp(-rate * ad_if)
    if approx:
        return rate, sig, (e.mean(axis=0) if e.ndim == 2 else e), one, one
    if kind == ABSORBING:
        return rate, sig, e, one, one
    fac = np.where(B.medium, rate, 1.0)
    if e.ndim == 2:
        return rate, sig, e, e.mean(axis=0), (e * fac).mean(axis=0)
    return rate, sig, e, e, e * fac


def _directed(stack, src: Side, tgt: Side, u, exit_top, l0, rng, pdf_mode, approx, nmax, out,
              hero=None):
    """Connections with the source's sampled direction (strategy u: 0 = L samples, 1 = R)."""
    N = stack.N
    n = src.n
    for (s, going_up), B in src.sources.items():
        l_if = s if going_up else s + 1   # the interface the direction reaches
        ad_if = np.abs(l_if - B.t)
        rate, sig, Tr_if, dens_t_if, dens_s_if = _slab_terms(stack, s, B, ad_if, l0, pdf_mode, approx, hero)
        negc = -B.c
        ker = stack.kernels[l_if]
        mo = None if ker.generic or ker.delta_only else ker.take(B.lane + l0).mask_terms(negc)
        for g, is_medium in ((l_if, False), (N + s, True)):
            G = tgt.targets.get(g)
            if G is None or (is_medium and approx):
                continue
            cnt = G.count[B.lane]
            sidx = np.flatnonzero(cnt)
            if not sidx.size:
                continue
            cnt = cnt[sidx]
            lo = G.start[B.lane[sidx]]
            acc = np.zeros(sidx.size) if pdf_mode else np.zeros((3, sidx.size))
            cum = np.cumsum(cnt)
            total = int(cum[-1])
            cuts = [0]
            if total > BLOCK:
                cuts += list(np.searchsorted(cum, np.arange(BLOCK, total, BLOCK), side="left") + 1)
            cuts.append(sidx.size)
            for a0, a1 in zip(cuts[:-1], cuts[1:]):
                if a1 <= a0:
                    continue
                cb = cnt[a0:a1]
                csum = np.cumsum(cb)
                tot = int(csum[-1])
                loc = np.repeat(np.arange(a1 - a0), cb)
                ti = np.repeat(lo[a0:a1] - (csum - cb), cb) + np.arange(tot)
                si = sidx[a0 + loc]
                if is_medium:
                    dt = G.t[ti] - B.t[si]
                    keep = (dt < 0) if going_up else (dt > 0)
                    if nmax is not None:
                        keep &= (B.k[si] + G.k[ti]) <= nmax[B.lane[si]]
                    if not keep.all():
                        sel = np.flatnonzero(keep)
                        loc, ti, si, dt = loc[sel], ti[sel], si[sel], dt[sel]
                        if not sel.size:
                            continue
                elif nmax is not None:
                    keep = (B.k[si] + G.k[ti]) <= nmax[B.lane[si]]
                    if not keep.all():
                        sel = np.flatnonzero(keep)
                        loc, ti, si = loc[sel], ti[sel], si[sel]
                        if not sel.size:
                            continue
                x = _block(stack, s, l_if, is_medium, B, G, si, ti, negc, rate, sig, dens_t_if,
                           dens_s_if, mo, u, l0, rng, pdf_mode)
                nb = a1 - a0
                if pdf_mode:
                    acc[a0:a1] += np.bincount(loc, x, minlength=nb)
                else:
                    for ch in range(3):
                        acc[ch, a0:a1] += np.bincount(loc, x[ch], minlength=nb)
            # per-source factors
            lanes_s = B.lane[sidx]
            if pdf_mode:
                f = B.gamma[sidx] if u == 0 else B.rev[sidx]
                if approx and not np.isscalar(Tr_if):
                    f = f * Tr_if[sidx]     # the pass probability of the slab (per source)
                out += np.bincount(lanes_s, acc * f, minlength=n)
            else:
                f = _t(B.thru1, sidx) * (stack.eta_corr(np.full(sidx.size, s), exit_top[lanes_s])
                                         / np.abs(B.c[2, sidx]))
                if not is_medium and not np.isscalar(Tr_if):
                    f = f * _t(Tr_if, sidx)
                acc = acc * f
                for ch in range(3):
                    out[ch] += np.bincount(lanes_s, acc[ch], minlength=n)


def _block(stack, s, l_if, is_medium, B, G, si, ti, negc, rate, sig, dens_t_if, dens_s_if, mo, u,
           l0, rng, pdf_mode):
    """Contributions of one block of connections (sources ``si`` of B, targets ``ti`` of G):
    value (3, m) without the per-source factors, or the pdf integrand ratio (m,)."""
    w = _t(negc, si)                  # from the target towards the source
    w_in = _t(G.w_in, ti)
    if is_medium:
        ad = np.abs(G.t[ti] - B.t[si])
        r = _t(rate, si)
        e = np.exp(-r * ad)
        if e.ndim == 2:
            dens_t = (r * e).mean(axis=0)
            dens_s = np.where(B.medium[si], dens_t, e.mean(axis=0))
        else:
            dens_t = r * e
            dens_s = np.where(B.medium[si], dens_t, e)
        ph = stack.slabs[s].phase.take(B.lane[si] + l0)
        v, pr = ph.connect(w_in, w, None if G.sig is None else G.sig[ti],
                           None if sig is None else sig[si])
        pf = v
    else:
        dens_t = dens_t_if[si]
        dens_s = dens_s_if[si]
        ker = stack.kernels[l_if]
        if not ker.constant:   # a constant kernel's take is itself: no per-connection lanes
            ker = ker.take(B.lane[si] + l0)
        if ker.generic:
            v, pf, pr = ker.eval(w_in, w, rng, True)
        elif G.mt is None or mo is None:
            v, pf, pr = ker.eval(w_in, w, rng, True, pdf_mode)
        else:
            v, pf, pr = ker.eval(w_in, w, rng, True, pdf_mode, ti=_t(G.mt, ti), to=_t(mo, si))
    S_src = pf * (B.A[si] + dens_s * B.B[si])
    S_tgt = dens_t * (G.c1[ti] + pr * G.c2[ti])
    wmis = 1.0 / (1.0 + S_src + S_tgt)
    if pdf_mode:
        if u == 0:
            return dens_t * pr * wmis * G.qbg[ti]
        return pf * dens_s * wmis * G.gamma[ti]
    x = wmis * v
    if is_medium:
        x = x * e
    return x * _t(G.thru0, ti)
