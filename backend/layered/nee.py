"""Unidirectional estimator of the layered BSDF: next-event estimation through the exit
interface with local MIS (Guo et al. 2018 §4.2.1, digest §6.1).

For a query (wi, wo) the exit interface E is the top if wo points up, else the bottom. Every path
leaves through E from a vertex that sees E directly: a medium vertex in the slab next to E, or a
vertex on the interface F across that slab. For each such vertex of the forward walk L two
strategies estimate the paths ending "vertex → E → wo":

* NEE: a direction u sampled from E's BSDF seen from outside (from wo, importance transport; one
  draw per lane, shared by the lane's vertices), connected to the vertex with the slab's
  transmittance. Generalised reciprocity turns the sample weight of wo → u into the value of the
  flow −u → wo: f(u → wo)·|cos wo| = weight · p · |cos wo| / |cos u| · (η_wo/η_u)².
* Continuation: the direction the walk sampled at the vertex; if it heads for E, the exit BSDF is
  evaluated with the transmittance to E (its expected value; the walk itself goes on).

The pair is weighted with the power heuristic of the two solid-angle densities (a delta exit or a
delta-sampled vertex leaves only one strategy). With ``mis=False`` (the benchmarks' "no MIS"
variant) NEE takes every path it can generate (weight 1 where E's sampler density is > 0) and the
continuation only the rest (delta vertices, directions E's sampler cannot reach): still unbiased. Paths are counted once: at the last vertex before
the exit. The single-reflection path (entry = exit interface) is added exactly by the caller.
"""
from __future__ import annotations

import numpy as np

from .connect import eval_vertex, safe_div
from .stack import GRAZING, BoundStack
from .walk import Records


def power(a, b):
    a2 = a * a
    den = a2 + b * b
    return np.where(den > 0, a2 / np.where(den > 0, den, 1.0), 0.0)


def unidirectional(stack: BoundStack, wo: np.ndarray, L: Records, rng, mis: bool = True) -> np.ndarray:
    """(3, n) sum of NEE and continuation terms per lane (importance transport, f·|cos θo|);
    ``wo`` is (3, n)."""
    n = L.n
    N = stack.N
    out = np.zeros((3, n))
    if N < 2:
        return out
    exit_top = wo[2] > 0
    E = np.where(exit_top, 0, N - 1)
    slab_E = np.where(exit_top, 0, N - 2)
    face = np.where(exit_top, 1, N - 2)
    # One refraction sample through the exit interface per lane, from outside.
    u = np.zeros((3, n))
    w_b = np.zeros((3, n))
    p_E = np.zeros(n)
    delta_E = np.zeros(n, dtype=bool)
    for e in (0, N - 1):
        lanes = np.flatnonzero(E == e)
        if not lanes.size:
            continue
        d, w, pf, _, dl = stack.kernels[e].take(lanes).sample(wo[:, lanes], rng)
        inward = (d[2] * wo[2, lanes] < 0) & (np.abs(d[2]) >= GRAZING)
        u[:, lanes] = d
        w_b[:, lanes] = np.where(inward, w, 0.0)
        p_E[lanes] = pf
        delta_E[lanes] = dl
    eta_corr = stack.eta_corr(slab_E, exit_top)
    # Normal-mapped exit interface: NEE converts E's sample weight (which carries |⟨n_E, u⟩|)
    # into the flow u → wo, whose exit segment carries |⟨n_E, wo⟩| instead of |cos θo|.
    exit_arr = np.ones(n)
    for e in (0, N - 1):
        if stack.kernels[e].framed:
            lanes = np.flatnonzero(E == e)
            exit_arr[lanes] = stack.kernels[e].take(lanes).arrival(wo[:, lanes])
    lane = L.lane
    eligible = ((L.kind == 0) & (L.layer == slab_E[lane])) | ((L.kind == 1) & (L.layer == face[lane]))
    rows = np.flatnonzero(eligible)
    if not rows.size:
        return out
    ln = lane[rows]
    t_E = E[ln].astype(np.float64)
    t_v = L.t[rows]
    # ------------------------------------------------------------------ NEE
    nee = np.flatnonzero(w_b[:, ln].max(axis=0) > 0)
    if nee.size:
        r, l2 = rows[nee], ln[nee]
        d = -u[:, l2]  # from the vertex towards E (pointing away from the vertex)
        val, p_v, _ = eval_vertex(stack, L, r, d, rng, need_rev=False)
        T = _transmittance(stack, slab_E[l2], l2, d, t_v[nee], t_E[nee])
        w = np.where(delta_E[l2], 1.0, power(p_E[l2], p_v) if mis else 1.0)
        factor = np.abs(wo[2, l2]) * exit_arr[l2] * safe_div(np.ones(nee.size), np.abs(u[2, l2])) \
            * eta_corr[l2] * w
        c = L.thru0[:, r] * val * T * w_b[:, l2] * factor
        for ch in range(3):
            out[ch] += np.bincount(l2, c[ch], minlength=n)
    # ------------------------------------------------------------------ continuation
    dz = L.w_out[2, rows]
    heads = np.where(exit_top[ln], dz > 0, dz < 0) & (L.thru1[:, rows].max(axis=0) > 0)
    cont = np.flatnonzero(heads)
    if cont.size:
        r, l2 = rows[cont], ln[cont]
        dc = L.w_out[:, r]
        T = _transmittance(stack, slab_E[l2], l2, dc, t_v[cont], t_E[cont])
        fE = np.zeros((3, cont.size))
        pE = np.zeros(cont.size)
        for e in (0, N - 1):
            pos = np.flatnonzero(E[l2] == e)
            if not pos.size:
                continue
            ker = stack.kernels[e]
            if ker.delta_only:
                continue
            # Flow −dc → wo at E; the density of E's sampler from wo towards −dc is its reverse.
            kt = ker.take(l2[pos])
            v, _, pr = kt.eval(-dc[:, pos], wo[:, l2[pos]], rng)
            fE[:, pos] = v * kt.arrival(-dc[:, pos])
            pE[pos] = pr
        w = np.where(L.delta[r], 1.0, power(L.pdf_fwd[r], pE) if mis else (pE <= 0) * 1.0)
        c = L.thru1[:, r] * T * fE * w
        for ch in range(3):
            out[ch] += np.bincount(l2, c[ch], minlength=n)
    return out


def _transmittance(stack: BoundStack, slab, lanes, d, t0, t1):
    T = np.zeros((3, d.shape[1]))
    for k in np.unique(slab):
        pos = np.flatnonzero(slab == k)
        T[:, pos] = stack.transmittance(int(k), lanes[pos], d[:, pos], t0[pos], t1[pos])
    return T
