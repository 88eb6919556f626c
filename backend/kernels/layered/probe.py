"""Array entry points into the parts of the layered code, for tests and inspection (never called
by the renderer): one interface's sample/eval with both densities, slab transmittance and depth
densities, free flights, and whole walks with their records (``backend/layered/probe.py`` wraps
them for NumPy callers). They loop over lanes calling the same per-lane functions as the walk
and the estimators."""
from __future__ import annotations

import math

from numba import njit

from ..rng import path_key
from . import estimators as es
from . import iface as ki
from . import phase as ph
from . import walk as wk
from .table import bind_iface, bind_into


@njit(cache=True, _nrt=False)
def bind_iface_rows(kind, dist, mask, values, tex, nmode, nval, ntex, TX, uv, B):
    for i in range(B.shape[0]):
        bind_iface(kind, dist, mask, values, tex, 0, nmode, (nval[0], nval[1], nval[2]), ntex, TX,
                   uv[i, 0], uv[i, 1], B[i], 0)


@njit(cache=True, _nrt=False)
def _ri(a, i):
    return i if a.shape[0] > 1 else 0


@njit(cache=True, _nrt=False)
def iface_eval(Bk, wi, wo, val, pf, pr):
    for i in range(wi.shape[0]):
        v, f, r = ki.evaluate(Bk[_ri(Bk, i)], 0, (wi[i, 0], wi[i, 1], wi[i, 2]),
                              (wo[i, 0], wo[i, 1], wo[i, 2]), math.nan, math.nan, False)
        val[i, 0], val[i, 1], val[i, 2] = v
        pf[i] = f
        pr[i] = r


@njit(cache=True, _nrt=False)
def iface_sample(Bk, wi, seed, R, wo, w, pf, pr, delta):
    for i in range(wi.shape[0]):
        R[0] = path_key(seed, i, 0)
        R[1] = 0
        d, ww, f, r, dl = ki.sample(Bk[_ri(Bk, i)], 0, (wi[i, 0], wi[i, 1], wi[i, 2]), ph.rnd(R),
                                    ph.rnd(R), ph.rnd(R), True)
        wo[i, 0], wo[i, 1], wo[i, 2] = d
        w[i, 0], w[i, 1], w[i, 2] = ww
        pf[i] = f
        pr[i] = r
        delta[i] = dl


@njit(cache=True, _nrt=False)
def bound_blocks(ST, TX, s, uv, out):
    for i in range(out.shape[0]):
        bind_into(ST, TX, s, uv[i, 0], uv[i, 1], out[i])


@njit(cache=True, _nrt=False)
def slab_transmittance(Bs, FT, k, d, t0, t1, out):
    for i in range(d.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = es.transmittance(Bs[_ri(Bs, i)], FT, k, (d[i, 0], d[i, 1], d[i, 2]),
                                                           t0[i], t1[i])


@njit(cache=True, _nrt=False)
def slab_depth_density(Bs, FT, k, d, t0, t1, to_medium, hero, out):
    for i in range(d.shape[0]):
        out[i] = wk.depth_density(Bs[_ri(Bs, i)], FT, k, (d[i, 0], d[i, 1], d[i, 2]), t0[i], t1[i],
                                  to_medium[i], hero[i])


@njit(cache=True, _nrt=False)
def walks(Bs, FT, w0, seed, purpose, approx, rr_start, rr_thr, cap, hero, W1, R, C,
          count, exit_dir, exit_w, exit_delta, hero_out, records):
    """One walk per lane; lane i's records are copied to records[i, :count[i]]."""
    for i in range(w0.shape[0]):
        R[0] = path_key(seed, i, 0)
        R[1] = 0
        n, d, w, dl, capped, h = wk.walk(Bs[_ri(Bs, i)], FT, (w0[i, 0], w0[i, 1], w0[i, 2]), W1, 0, R,
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


@njit(cache=True, _nrt=False)
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
