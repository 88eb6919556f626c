"""The lock-step random walk through a layer stack (Guo et al. 2018 §4.1 / digest §5).

All lanes walk together; each iteration every live lane makes exactly one vertex (an interface
hit or a scattering event in a medium), so vertex i of every lane is produced in iteration i.
Finished lanes (exited, absorbed by roulette, failed samples) drop out by compaction.

Transport: every interface is sampled in IMPORTANCE mode, so a walk started from direction ``w``
is a photon-like flux walk: its throughput after the exit vertex estimates
f(w → w_exit)·|cos w_exit| / p(w_exit) for light arriving from w (``sample``); the estimators
convert to the requested transport mode at the end (bsdf.py).

Records (``record=True``): one row per vertex, sorted by (lane, vertex index), with everything the
estimators need (directions point away from the vertex, as for BSDFs):

  kind          1 interface, 0 medium;  layer: interface index or slab index;  t: global depth
  w_in, w_out   towards the previous vertex / the sampled next one (w_in of vertex 1 = start)
  thru0, thru1  throughput arriving at the vertex / after its sampled direction (RGB)
  gamma         product of 1/(survival probability) and, for the approximate pdf, slab pass
                probabilities: the walk's weight in the pdf integrand (a scalar)
  pdf_fwd       density of w_out given w_in (1 for delta samples: a placeholder, see connect.py)
  pdf_rev       density of w_in given w_out (the reverse walk's choice), 1 for delta samples
  dens_fwd      density of this vertex's depth along the incoming edge (per unit depth for a
                medium vertex, a pass probability for an interface), 1 for the first vertex
  dens_rev      density of the previous vertex's depth sampled backwards along the same edge
  pdf_fwd_prev, delta_prev   the previous vertex's pdf_fwd and delta
  delta         the sampled direction came from a delta lobe
  P, Q          running MIS sums/products of the bidirectional estimator (connect.py)

Termination: unbiased Russian roulette on the throughput after ``RR_START`` vertices, and a hard
cap ``max_vertices`` whose hits are counted (``WalkResult.capped``) — never silent.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..materials.base import IMPORTANCE
from .stack import ABSORBING, EMPTY, GRAZING, SCATTERING, BoundStack

RR_START = 4        # vertices before roulette may end a walk
RR_THRESHOLD = 0.1  # survival probability = min(1, max channel of throughput / this)

FIELDS_F = ("t", "pdf_fwd", "pdf_rev", "dens_fwd", "dens_rev", "pdf_fwd_prev", "P", "Q", "gamma")
FIELDS_V = ("w_in", "w_out", "thru0", "thru1")
FIELDS_I = ("lane", "k", "kind", "layer", "delta", "delta_prev")


class Records:
    """Struct of arrays, one row per vertex, rows of a lane contiguous and in walk order."""

    def __init__(self, n: int, chunks: list[dict]):
        self.n = n
        if chunks:
            cat = {f: np.concatenate([c[f] for c in chunks]) for f in chunks[0]}
        else:
            cat = {f: np.zeros((0, 3) if f in FIELDS_V else 0) for f in FIELDS_F + FIELDS_V + FIELDS_I}
        lane = cat["lane"]
        self.count = np.bincount(lane, minlength=n).astype(np.int64)
        self.offset = np.concatenate([[0], np.cumsum(self.count)[:-1]]).astype(np.int64)
        dest = self.offset[lane] + cat["k"] - 1
        for f, v in cat.items():
            out = np.empty_like(v)
            out[dest] = v
            setattr(self, f, out)
        self.size = lane.size


@dataclass
class WalkResult:
    exit_dir: np.ndarray     # (n, 3) direction the walk left the stack (0 if it did not)
    exit_weight: np.ndarray  # (n, 3) throughput after the exit vertex (0 if it did not exit)
    exit_delta: np.ndarray   # (n,) every vertex of the path was a delta sample
    records: Records | None
    vertices: int            # total vertices made
    capped: int              # walks stopped by the vertex cap (biased energy loss, reported)


def _compact(S: dict, keep: np.ndarray) -> dict:
    if keep.all():
        return S
    sel = np.flatnonzero(keep)
    return {k: v[sel] for k, v in S.items()}


def _safe_ratio(a, b):
    ok = b > 0
    return np.where(ok, a / np.where(ok, b, 1.0), 0.0)


def walk(stack: BoundStack, w0: np.ndarray, rng: np.random.Generator, record: bool = True,
         approx: bool = False, max_vertices: int = 1024) -> WalkResult:
    """Walk from direction ``w0`` (pointing away from the surface, (n, 3)): enter at the top if
    w0_z > 0, else at the bottom. ``approx``: media do not scatter (crossing a slab multiplies
    ``gamma`` by its pass probability), for the approximate pdf."""
    n = w0.shape[0]
    N = stack.N
    exit_dir = np.zeros((n, 3))
    exit_weight = np.zeros((n, 3))
    exit_delta = np.zeros(n, dtype=bool)
    chunks: list[dict] = []

    top = w0[:, 2] > 0
    layer0 = np.where(top, 0, N - 1).astype(np.int64)
    # Per-lane state. c_* are carried from the previous vertex for the MIS recurrences.
    S = {
        "lane": np.arange(n), "kind": np.ones(n, dtype=np.int8), "layer": layer0,
        "t": layer0.astype(np.float64), "d_in": -w0, "beta": np.ones((n, 3)), "gamma": np.ones(n),
        "all_delta": np.ones(n, dtype=bool), "dens_fwd": np.ones(n), "dens_rev": np.ones(n),
        "c_dens_fwd": np.ones(n), "c_pdf_rev": np.ones(n), "c_pdf_fwd": np.ones(n),
        "c_pdf_fwd_prev": np.ones(n), "c_delta": np.zeros(n, dtype=bool),
        "c_delta_prev": np.zeros(n, dtype=bool), "c_P": np.zeros(n), "c_Q": np.zeros(n),
    }
    # A start direction in the surface plane cannot enter the stack.
    S = _compact(S, np.abs(w0[:, 2]) > 0)

    vertices = 0
    capped = 0
    i = 1
    while S["lane"].size:
        lane, kind, layer, t, d_in = S["lane"], S["kind"], S["layer"], S["t"], S["d_in"]
        m = lane.size
        vertices += m
        # ---------------------------------------------------------------- MIS recurrences
        if record:
            if i >= 3:
                r_z = _safe_ratio(S["dens_rev"], S["c_dens_fwd"])
                r_d = _safe_ratio(S["c_pdf_rev"], S["c_pdf_fwd_prev"])
                P = r_z * ((~S["c_delta"]) + r_d * ((~S["c_delta_prev"]) + S["c_P"]))
                Q = r_z * r_d * S["c_Q"]
            elif i == 2:
                P = np.zeros(m)
                Q = S["c_pdf_rev"] * S["dens_rev"]
            else:
                P = np.zeros(m)
                Q = np.zeros(m)
        # ---------------------------------------------------------------- sample the vertex
        w_in = -d_in
        d_out = np.zeros((m, 3))
        wgt = np.zeros((m, 3))
        pdf_fwd = np.ones(m)
        pdf_rev = np.ones(m)
        delta = np.zeros(m, dtype=bool)
        is_if = kind == 1
        for l in range(N):
            pos = np.flatnonzero(is_if & (layer == l))
            if not pos.size:
                continue
            bsdf = stack.ifaces[l].take(lane[pos])
            wi = w_in[pos]
            s = bsdf.sample(wi, rng, IMPORTANCE)
            d_out[pos] = s.wo
            wgt[pos] = s.weight
            delta[pos] = s.delta
            pdf_fwd[pos] = np.where(s.delta, 1.0, s.pdf)
            if record:
                nd = np.flatnonzero(~s.delta)
                if nd.size == pos.size:
                    pdf_rev[pos] = bsdf.pdf(s.wo, wi, rng, IMPORTANCE)
                elif nd.size:
                    pdf_rev[pos[nd]] = bsdf.take(nd).pdf(s.wo[nd], wi[nd], rng, IMPORTANCE)
        if not is_if.all():
            for k in range(N - 1):
                pos = np.flatnonzero((~is_if) & (layer == k))
                if not pos.size:
                    continue
                phase = stack.media[k].phase.take(lane[pos])
                di = d_in[pos]
                ps = phase.sample(di, rng)
                d_out[pos] = ps.d_out
                wgt[pos] = ps.weight[:, None]
                pdf_fwd[pos] = ps.pdf
                if record:
                    pdf_rev[pos] = phase.pdf(-ps.d_out, -di)
        beta = S["beta"]
        thru1 = beta * wgt
        if record:
            chunks.append({
                "lane": lane, "k": np.full(m, i, dtype=np.int64), "kind": kind, "layer": layer,
                "t": t, "w_in": w_in, "w_out": d_out, "thru0": beta, "thru1": thru1,
                "gamma": S["gamma"], "pdf_fwd": pdf_fwd, "pdf_rev": pdf_rev,
                "dens_fwd": S["dens_fwd"], "dens_rev": S["dens_rev"], "pdf_fwd_prev": S["c_pdf_fwd"],
                "delta": delta, "delta_prev": S["c_delta"], "P": P, "Q": Q,
            })
            S["c_dens_fwd"], S["c_pdf_rev"] = S["dens_fwd"], pdf_rev
            S["c_pdf_fwd_prev"], S["c_delta_prev"] = S["c_pdf_fwd"], S["c_delta"]
            S["c_pdf_fwd"], S["c_delta"], S["c_P"], S["c_Q"] = pdf_fwd, delta, P, Q
        S["beta"] = beta = thru1
        S["all_delta"] = S["all_delta"] & delta & is_if
        # ---------------------------------------------------------------- move
        up = d_out[:, 2] > 0
        exits = is_if & ((up & (layer == 0)) | (~up & (layer == N - 1)))
        if exits.any():
            e = np.flatnonzero(exits)
            exit_dir[lane[e]] = d_out[e]
            exit_weight[lane[e]] = beta[e]
            exit_delta[lane[e]] = S["all_delta"][e]
        S["slab"] = np.where(is_if, np.where(up, layer - 1, layer), layer)
        S["up"] = up
        S["d_in"] = d_out
        alive = (~exits) & (np.abs(d_out[:, 2]) >= GRAZING) & np.any(beta > 0, axis=1)
        if i >= RR_START:
            q = np.minimum(1.0, beta.max(axis=1) / RR_THRESHOLD)
            alive &= rng.random(m) < q
            inv_q = 1.0 / np.where(q > 0, q, 1.0)
            S["beta"] = beta * inv_q[:, None]
            S["gamma"] = S["gamma"] * inv_q
        if i >= max_vertices:
            capped += int(alive.sum())
            break
        S = _compact(S, alive)
        if not S["lane"].size:
            break
        # ---------------------------------------------------------------- free flights
        lane, t, d, slab, up = S["lane"], S["t"], S["d_in"], S["slab"], S["up"]
        m = lane.size
        prev_medium = S["kind"] == 0
        new_kind = np.ones(m, dtype=np.int8)
        new_layer = np.where(up, slab, slab + 1)
        new_t = new_layer.astype(np.float64)
        dens_fwd = np.ones(m)
        dens_rev = np.ones(m)
        # Copies: the record chunks share these arrays.
        beta, gamma = S["beta"].copy(), S["gamma"].copy()
        for k in range(N - 1):
            pos = np.flatnonzero(slab == k)
            if not pos.size:
                continue
            kd = stack.kinds[k]
            if kd == EMPTY:
                continue
            if approx or kd == ABSORBING:
                tr = stack.transmittance(k, lane[pos], d[pos], t[pos], new_t[pos])
                if approx:
                    gamma[pos] = gamma[pos] * tr.mean(axis=1)
                else:
                    beta[pos] = beta[pos] * tr
                continue
            med = stack.media[k].take(lane[pos])
            dk = d[pos]
            s0 = t[pos] - k
            ff = med.free_flight(s0, dk, rng)
            beta[pos] = beta[pos] * ff.weight
            sc = ff.scattered
            new_t[pos] = k + ff.depth
            new_kind[pos] = np.where(sc, 0, 1)
            new_layer[pos] = np.where(sc, k, new_layer[pos])
            dens_fwd[pos] = ff.pdf
            if record:
                dens_rev[pos] = med.free_flight_pdf(ff.depth, s0, -dk, prev_medium[pos])
        S["kind"], S["layer"], S["t"] = new_kind, new_layer, new_t
        S["dens_fwd"], S["dens_rev"] = dens_fwd, dens_rev
        S["beta"], S["gamma"] = beta, gamma
        S = _compact(S, np.any(beta > 0, axis=1))
        i += 1
    return WalkResult(exit_dir, exit_weight, exit_delta, Records(n, chunks) if record else None,
                      vertices, capped)
