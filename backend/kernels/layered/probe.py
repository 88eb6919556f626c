"""Array entry points into the parts of the layered code, for tests and inspection (never called
by the renderer): one interface's sample/eval with both densities, slab transmittance and depth
densities, free flights, and whole walks with their records (``backend/layered/probe.py`` wraps
them for NumPy callers). They loop over lanes calling the same per-lane functions as the walk
and the estimators."""
from __future__ import annotations

from collections import namedtuple

import math

from ..jit import kernel
from ..rng import path_key
from . import estimators as es
from . import iface as ki
from . import phase as ph
from . import walk as wk
from .table import HEAD, M_DIR, M_PH, MED0, MSTRIDE, UNIT_DUV, IfaceRow, bind_iface, bind_into


@kernel
def bind_iface_rows(kind, dist, mask, values, tex, nmode, nval, ntex, TX, uv, B):
    for i in range(B.shape[0]):
        row = IfaceRow(kind, dist, mask, values, tex, 0, nmode, (nval[0], nval[1], nval[2]), ntex, bump=False)
        bind_iface(row, TX, uv[i, 0], uv[i, 1], UNIT_DUV, B[i], 0)


@kernel
def _ri(a, i):
    return i if a.shape[0] > 1 else 0


@kernel
def iface_eval(Bk, wi, wo, val, pf, pr):
    for i in range(wi.shape[0]):
        v, f, r = ki.evaluate(Bk[_ri(Bk, i)], 0, (wi[i, 0], wi[i, 1], wi[i, 2]),
                              (wo[i, 0], wo[i, 1], wo[i, 2]), math.nan, math.nan, pdf_only=False)
        val[i, 0], val[i, 1], val[i, 2] = v
        pf[i] = f
        pr[i] = r


@kernel
def iface_sample(Bk, wi, seed, R, wo, w, pf, pr, delta):
    for i in range(wi.shape[0]):
        R[0] = path_key(seed, i, 0)
        R[1] = 0
        d, ww, f, r, dl = ki.sample(Bk[_ri(Bk, i)], 0, (wi[i, 0], wi[i, 1], wi[i, 2]), ph.rnd(R),
                                    ph.rnd(R), ph.rnd(R), dens=True)
        wo[i, 0], wo[i, 1], wo[i, 2] = d
        w[i, 0], w[i, 1], w[i, 2] = ww
        pf[i] = f
        pr[i] = r
        delta[i] = dl


@kernel
def bound_blocks(ST, TX, s, uv, out):
    for i in range(out.shape[0]):
        bind_into(ST, TX, s, uv[i, 0], uv[i, 1], UNIT_DUV, out[i])


@kernel
def slab_transmittance(Bs, FT, k, d, t0, t1, out):
    for i in range(d.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = wk.transmittance(Bs[_ri(Bs, i)], FT, k, (d[i, 0], d[i, 1], d[i, 2]),
                                                           t0[i], t1[i])


@kernel
def slab_depth_density(Bs, FT, k, d, t0, t1, to_medium, hero, out):
    for i in range(d.shape[0]):
        out[i] = wk.depth_density(Bs[_ri(Bs, i)], FT, k, (d[i, 0], d[i, 1], d[i, 2]), t0[i], t1[i],
                                  to_medium[i], hero[i])


#: How ``walks`` walks: what the records are for (walk.NONE, …), the approximate pdf, Russian
#: roulette's start and threshold, the vertex cap.
WalkSpec = namedtuple("WalkSpec", ["purpose", "approx", "rr_start", "rr_thr", "cap"])
#: What ``walks`` returns per lane: the vertex count, exit direction, weight and delta flag, the
#: hero channel, and the records (lanes × vertices × walk.NF).
WalkOut = namedtuple("WalkOut", ["count", "exit_dir", "exit_w", "exit_delta", "hero", "records"])


@kernel
def walks(Bs, FT, w0, seed, spec, hero, W1, R, C, out):
    """One walk per lane (``spec``: a WalkSpec; ``out``: a WalkOut); lane i's records are copied
    to out.records[i, :out.count[i]]."""
    purpose, approx, rr_start, rr_thr, cap = spec
    count, exit_dir, exit_w, exit_delta, hero_out, records = out
    for i in range(w0.shape[0]):
        R[0] = path_key(seed, i, 0)
        R[1] = 0
        n, d, w, dl, capped, h = wk.run(Bs[_ri(Bs, i)], FT, (w0[i, 0], w0[i, 1], w0[i, 2]), W1, 0, R,
                                         purpose, approx, rr_start, rr_thr, cap, hero[i])
        C[0] += capped
        count[i] = n
        exit_dir[i, 0], exit_dir[i, 1], exit_dir[i, 2] = d
        exit_w[i, 0], exit_w[i, 1], exit_w[i, 2] = w
        exit_delta[i] = dl
        hero_out[i] = h
        if purpose != wk.NONE:
            for j in range(n):
                for f in range(wk.NF):
                    records[i, j, f] = W1[0, j, f]


@kernel
def connect(Bs, FT, recL, nL, recR, nR, wo, pdf_mode, approx, nmax, hero, W2, out3, outp):
    """The bidirectional sums of given walk pairs (records as ``walks`` returns them)."""
    for i in range(wo.shape[0]):
        for j in range(nL[i]):
            for f in range(wk.NF):
                W2[0, j, f] = recL[i, j, f]
        for j in range(nR[i]):
            for f in range(wk.NF):
                W2[1, j, f] = recR[i, j, f]
        v, p = es.bidirectional(Bs[_ri(Bs, i)], FT, W2, nL[i], nR[i], wo[i, 2] > 0.0, pdf_mode, approx,
                                nmax[i], hero[i])
        out3[i, 0], out3[i, 1], out3[i, 2] = v
        outp[i] = p


@kernel
def vertex_eval(Bs, FT, kind, layer, lane, w_in, w, pdf_only, val, pf, pr):
    """The vertex function of recorded walk vertices for an outgoing direction w: interface
    f(w_in → w)·|cos w| (importance) or the phase p(−w_in → w), with the forward density of w
    and the reverse density of w_in."""
    for i in range(w.shape[0]):
        B = Bs[_ri(Bs, lane[i])]
        a = (w_in[i, 0], w_in[i, 1], w_in[i, 2])
        b = (w[i, 0], w[i, 1], w[i, 2])
        if kind[i] == 1:
            v, f, r = ki.evaluate(B, HEAD + layer[i] * ki.STRIDE, a, b, math.nan, math.nan, pdf_only)
        else:
            mo = MED0 + layer[i] * MSTRIDE
            s_a = ph.sigma_scale(B, mo + M_PH, FT, a)
            s_b = ph.sigma_scale(B, mo + M_PH, FT, b)
            f, r = ph.connect(B, mo + M_PH, FT, a, b, s_a, s_b)
            v = (f, f, f)
        val[i, 0], val[i, 1], val[i, 2] = v
        pf[i] = f
        pr[i] = r


@kernel
def slab_flights(Bs, FT, k, s0, d, hero, seed, R, new_s, scattered, weight, dens):
    """One free flight per lane in slab k from normalised depth s0 along d (the walk's
    ``flight``: chromatic slabs with the lane's hero channel and fresh spectral ratios)."""
    mo = MED0 + k * MSTRIDE
    for i in range(d.shape[0]):
        R[0] = path_key(seed, i, 0)
        R[1] = 0
        B = Bs[_ri(Bs, i)]
        di = (d[i, 0], d[i, 1], d[i, 2])
        if not abs(di[2]) >= wk.GRAZING:
            new_s[i] = s0[i]
            scattered[i] = False
            weight[i, 0] = weight[i, 1] = weight[i, 2] = 0.0
            dens[i] = 0.0
            continue
        sig = ph.sigma_scale(B, mo + M_PH, FT, di) if B[mo + M_DIR] > 0.0 else 1.0
        sc, s1, fac, _, _, p, _ = wk.flight(B, mo, s0[i], di, sig, False, False, False, hero[i],
                                            (1.0, 1.0, 1.0), R)
        new_s[i] = s1
        scattered[i] = sc
        weight[i, 0], weight[i, 1], weight[i, 2] = fac
        dens[i] = p
