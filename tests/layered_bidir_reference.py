"""A pair-list implementation of the layered bidirectional connections in NumPy (every
(L vertex, R vertex) pair of a lane enumerated, then masked; the first NumPy implementation),
kept as an independent reference: tests/test_layered_connect.py checks that the compiled
connections (backend/kernels/layered/estimators.py) give the same sums on the same walks. The
stack is read through ``StackView`` (the compiled code's slab functions, backend/layered/probe)."""
import numpy as np

from backend.kernels.layered.walk import GRAZING
from backend.layered.probe import describe, eval_at as _eval_at, slab_depth_density, slab_transmittance

SLAB_KINDS = {"empty": 0, "absorbing": 1, "scattering": 2}


class StackView:
    """What the reference reads of a bound layered BSDF (constant stacks)."""

    def __init__(self, bsdf):
        self.bsdf = bsdf
        d = describe(bsdf)
        self.N = d["N"]
        self.kinds = [SLAB_KINDS[m["kind"]] for m in d["media"]]
        self.eta_top, self.eta_bottom = d["eta_top"], d["eta_bottom"]
        self.eta_slab = np.asarray(d["eta_slab"])

    def eta_corr(self, slab, exit_top):
        out = np.where(exit_top, self.eta_top, self.eta_bottom)
        return (out / self.eta_slab[slab]) ** 2

    def transmittance(self, k, lanes, d, t0, t1):
        return np.ascontiguousarray(slab_transmittance(self.bsdf, k, d.T, t0, t1).T)

    def pass_probability(self, k, lanes, d, t0, t1):
        return self.transmittance(k, lanes, d, t0, t1).mean(axis=0)

    def depth_pdf(self, k, lanes, d, t0, t1, to_medium, channel=None):
        return slab_depth_density(self.bsdf, k, d.T, t0, t1, to_medium, channel)


def eval_at(stack, kind, layer, lane, w_in, w, rng=None, pdf_only=False):
    return _eval_at(stack.bsdf, kind, layer, lane, w_in, w, pdf_only)

MAX_PAIRS = 1 << 19


def _inv(x):
    ok = x > 0
    return np.where(ok, 1.0 / np.where(ok, x, 1.0), 0.0)


class ConnView:
    """The records in lane-major order, with the MIS recurrences folded into a few coefficients
    per vertex (backend/kernels/layered/walk.py, estimators.py): for vertex X_i with dens = dens_fwd, pf = pdf_fwd, pr = pdf_rev,

        inv_dens = 1/dens (0 for the first vertex: no earlier strategies move through it)
        a   = (¬δ_prev + P) / pdf_fwd_prev
        own = ¬δ,  inv_pf = 1/pf,  b1 = inv_dens·(own + pr·a)
        S_evaluated(dens_in, pdfrev) = dens_in·inv_dens·(1 + pdfrev·a)
        S_sampled(dens_in, pdf_other) = pdf_other·inv_pf·(own + dens_in·b1)

    and for the pdf estimator (Q): qb = inv_dens·Q/pdf_fwd_prev (1 for the first vertex)."""

    def __init__(self, rec):
        p = rec.perm
        self.count, self.offset, self.n = rec.count, rec.offset, rec.n
        take = lambda x: x[..., p]  # noqa: E731
        self.lane = take(rec.lane)
        self.k = take(rec.k)
        self.t = take(rec.t)
        self.kind = take(rec.kind)
        self.layer = take(rec.layer)
        iface = self.kind == 1
        self.lo = np.where(iface, self.layer - 1, self.layer)   # slabs the vertex can connect in
        self.hi = self.layer
        self.w_in = take(rec.w_in)
        self.w_out = take(rec.w_out)
        pf, pr = take(rec.pdf_fwd), take(rec.pdf_rev)
        first = self.k == 1
        # The previous vertex's forward density and delta flag (the walk starts with 1, False).
        prev = np.arange(pf.size) - 1
        pf_prev = np.where(first, 1.0, pf[np.maximum(prev, 0)]) if pf.size else pf
        dl_prev = np.where(first, False, take(rec.delta)[np.maximum(prev, 0)]) if pf.size else first
        self.inv_dens = np.where(first, 0.0, _inv(take(rec.dens_fwd)))
        self.a = ((~dl_prev) + take(rec.P)) * _inv(pf_prev)
        delta = take(rec.delta)
        self.own = (~delta) * 1.0
        self.inv_pf = _inv(pf)
        self.pdf_rev = pr
        self.b1 = self.inv_dens * (self.own + pr * self.a)
        if rec.purpose == "value":
            self.thru0 = take(rec.thru0)
            self.thru1 = take(rec.thru1)
            self.live_out = self.thru1.max(axis=0) > 0
        else:
            self.gamma = take(rec.gamma)
            self.qb = np.where(first, 1.0, self.inv_dens * take(rec.Q) * _inv(pf_prev))
            self.live_out = pf > 0




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


def bidirectional(stack, wo: np.ndarray, L, R, rng,
                  pdf_mode: bool = False, approx: bool = False, nmax: np.ndarray | None = None,
                  hero: np.ndarray | None = None):
    """Sum over all connections per lane: (3, n) f·|cos θo| / |cos θo| (i.e. without the final
    cosine, without the single-interface term and before any transport-mode factor) or, with
    ``pdf_mode``, (n,) the pdf estimate. ``wo`` is (3, n). ``nmax`` (per lane) keeps only paths
    of at most that many vertices (approximate pdf). ``hero`` (n,): the channel whose depth
    densities a stochastic pdf uses in chromatic media (both walks' shared hero)."""
    n = L.n
    Lv, Rv = ConnView(L), ConnView(R)
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
                               exit_top, rng, pdf_mode, approx, hero)
            if pdf_mode:
                out += np.bincount(pl[sel], contrib, minlength=n)
            else:
                for ch in range(3):
                    out[ch] += np.bincount(pl[sel], contrib[ch], minlength=n)
    return out


def _connect(stack, L, R, iL, iR, pl, slab, u, exit_top, rng, pdf_mode, approx, hero=None):
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
            ch = None if hero is None else hero[lanes]
            a = stack.depth_pdf(k, lanes, ck, t0, t1, sl(kR) == 0, ch)
            b = stack.depth_pdf(k, lanes, -ck, t1, t0, sl(kL) == 0, ch)
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
