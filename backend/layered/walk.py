"""The lock-step random walk through a layer stack (Guo et al. 2018 §4.1 / digest §5).

All lanes walk together; each iteration every live lane makes exactly one vertex (an interface
hit or a scattering event in a medium), so vertex i of every lane is produced in iteration i.
Finished lanes (exited, absorbed by roulette, failed samples) drop out by compaction.

Transport: every interface is sampled in IMPORTANCE mode, so a walk started from direction ``w``
is a photon-like flux walk: its throughput after the exit vertex estimates
f(w → w_exit)·|cos w_exit| / p(w_exit) for light arriving from w (``sample``); the estimators
convert to the requested transport mode at the end (bsdf.py).

Records (``record=True``): one entry per vertex (see :class:`Records` for the order), with what
the estimators need (directions point away from the vertex, as for BSDFs):

  kind          1 interface, 0 medium;  layer: interface index or slab index;  t: global depth
  w_in, w_out   towards the previous vertex / the sampled next one (w_in of vertex 1 = start)
  thru0, thru1  throughput arriving at the vertex / after its sampled direction (RGB)
  gamma         product of 1/(survival probability) and, for the approximate pdf, slab pass
                probabilities: the walk's weight in the pdf integrand (a scalar)
  pdf_fwd       density of w_out given w_in (1 for delta samples: a placeholder, see connect.py)
  pdf_rev       density of w_in given w_out (the reverse walk's choice), 1 for delta samples
  dens_fwd      density of this vertex's depth along the incoming edge (per unit depth for a
                medium vertex, a pass probability for an interface), 1 for the first vertex
  pdf_fwd_prev, delta_prev   the previous vertex's pdf_fwd and delta
  delta         the sampled direction came from a delta lobe
  P, Q          running MIS sums/products of the bidirectional estimator (connect.py)

Termination: unbiased Russian roulette on the throughput (``rr``), and a hard cap
``max_vertices`` whose hits are counted (``WalkResult.capped``) — never silent.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..materials.base import IMPORTANCE
from .stack import ABSORBING, EMPTY, GRAZING, SCATTERING, BoundStack

# Russian roulette: after vertex ``start`` a walk survives with probability
# min(1, max channel of throughput / threshold). Walks feeding the estimators (eval, pdf) use an
# aggressive setting: their connection cost grows with the square of the walk length while the
# variance barely changes (measured: Fig. 2 stack, 3x faster at +3 % variance). Walks that
# *are* the sample (``sample``) keep a mild one: their weight goes straight into the image.
RR_EVAL = (2, 1.0)
RR_SAMPLE = (4, 0.25)

class Records:
    """Struct of arrays, one entry (column for vectors) per vertex, in the order the walk made
    them (iteration-major). ``perm`` lists the entries lane by lane: lane l's vertices, in walk
    order, are ``perm[offset[l] : offset[l] + count[l]]`` (no re-sorting of every field)."""

    def __init__(self, n: int, chunks: list[dict]):
        self.n = n
        keys = chunks[0].keys() if chunks else ("lane", "k")
        for f in keys:
            v = [c[f] for c in chunks]
            setattr(self, f, np.concatenate(v, axis=-1) if v else np.zeros(0, dtype=np.int64))
        lane = self.lane
        self.count = np.bincount(lane, minlength=n).astype(np.int64)
        self.offset = np.concatenate([[0], np.cumsum(self.count)[:-1]]).astype(np.int64)
        self.perm = np.empty(lane.size, dtype=np.int64)
        self.perm[self.offset[lane] + self.k - 1] = np.arange(lane.size)
        self.size = lane.size
        self._view = None

    def view(self) -> "ConnView":
        """Lane-major arrays for the bidirectional connections (computed once)."""
        if self._view is None:
            self._view = ConnView(self)
        return self._view


def _inv(x):
    ok = x > 0
    return np.where(ok, 1.0 / np.where(ok, x, 1.0), 0.0)


class ConnView:
    """The records in lane-major order, with the MIS recurrences folded into a few coefficients
    per vertex (connect.py): for vertex X_i with dens = dens_fwd, pf = pdf_fwd, pr = pdf_rev,

        inv_dens = 1/dens (0 for the first vertex: no earlier strategies move through it)
        a   = (¬δ_prev + P) / pdf_fwd_prev
        own = ¬δ,  inv_pf = 1/pf,  b1 = inv_dens·(own + pr·a)
        S_evaluated(dens_in, pdfrev) = dens_in·inv_dens·(1 + pdfrev·a)
        S_sampled(dens_in, pdf_other) = pdf_other·inv_pf·(own + dens_in·b1)

    and for the pdf estimator (Q): qb = inv_dens·Q/pdf_fwd_prev (1 for the first vertex)."""

    def __init__(self, rec: "Records"):
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
        self.inv_dens = np.where(first, 0.0, _inv(take(rec.dens_fwd)))
        self.a = ((~take(rec.delta_prev)) + take(rec.P)) * _inv(take(rec.pdf_fwd_prev))
        delta = take(rec.delta)
        self.own = (~delta) * 1.0
        self.inv_pf = _inv(pf)
        self.pdf_rev = pr
        self.b1 = self.inv_dens * (self.own + pr * self.a)
        if hasattr(rec, "thru0"):
            self.thru0 = take(rec.thru0)
            self.thru1 = take(rec.thru1)
            self.live_out = self.thru1.max(axis=0) > 0
        else:
            self.gamma = take(rec.gamma)
            self.qb = np.where(first, 1.0, self.inv_dens * take(rec.Q) * _inv(take(rec.pdf_fwd_prev)))
            self.live_out = pf > 0


@dataclass
class WalkResult:
    exit_dir: np.ndarray     # (3, n) direction the walk left the stack (0 if it did not)
    exit_weight: np.ndarray  # (3, n) throughput after the exit vertex (0 if it did not exit)
    exit_delta: np.ndarray   # (n,) every vertex of the path was a delta sample
    records: Records | None
    vertices: int            # total vertices made
    capped: int              # walks stopped by the vertex cap (biased energy loss, reported)


def _compact(S: dict, keep: np.ndarray) -> dict:
    if keep.all():
        return S
    sel = np.flatnonzero(keep)
    return {k: v[..., sel] for k, v in S.items()}


def _safe_ratio(a, b):
    ok = b > 0
    return np.where(ok, a / np.where(ok, b, 1.0), 0.0)


def walk(stack: BoundStack, w0: np.ndarray, rng: np.random.Generator, record: bool = True,
         approx: bool = False, max_vertices: int = 1024, rr: tuple = RR_EVAL,
         purpose: str = "value") -> WalkResult:
    """Walk from direction ``w0`` ((3, n), pointing away from the surface): enter at the top if
    w0_z > 0, else at the bottom. ``approx``: media do not scatter (crossing a slab multiplies
    ``gamma`` by its pass probability), for the approximate pdf. ``purpose`` selects the recorded
    fields: "value" (throughputs, for eval) or "pdf" (``Q`` and ``gamma``, for the pdf)."""
    want_value = purpose == "value"
    n = w0.shape[1]
    N = stack.N
    exit_dir = np.zeros((3, n))
    exit_weight = np.zeros((3, n))
    exit_delta = np.zeros(n, dtype=bool)
    chunks: list[dict] = []

    layer0 = np.where(w0[2] > 0, 0, N - 1).astype(np.int64)
    S = {
        "lane": np.arange(n), "kind": np.ones(n, dtype=np.int8), "layer": layer0,
        "t": layer0.astype(np.float64), "d_in": -w0, "beta": np.ones((3, n)), "gamma": np.ones(n),
        "all_delta": np.ones(n, dtype=bool),
    }
    if record:
        S.update({"dens_fwd": np.ones(n), "dens_rev": np.ones(n), "c_dens_fwd": np.ones(n),
                  "c_pdf_rev": np.ones(n), "c_pdf_fwd": np.ones(n), "c_pdf_fwd_prev": np.ones(n),
                  "c_delta": np.zeros(n, dtype=bool), "c_delta_prev": np.zeros(n, dtype=bool),
                  "c_P": np.zeros(n), "c_Q": np.zeros(n)})
    chromatic = any(sl is not None and not sl.grey and k == SCATTERING
                    for sl, k in zip(stack.slabs, stack.kinds)) and not approx
    if chromatic:
        # Path-level spectral MIS (slab.py): one hero channel per walk, density ratios r.
        S["hero"] = np.minimum((rng.random(n) * 3.0).astype(np.int64), 2)
        S["r"] = np.ones((3, n))
    # A start direction in the surface plane cannot enter the stack.
    S = _compact(S, w0[2] != 0)

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
                P = Q = np.zeros(m)
        # ---------------------------------------------------------------- sample the vertex
        w_in = -d_in
        is_if = kind == 1
        all_if = bool(is_if.all())
        if all_if and N == 1:
            groups_if = [(0, None)]
        else:
            groups_if = [(l, np.flatnonzero(is_if & (layer == l))) for l in range(N)]
        if all_if:
            groups_m = []
        else:
            groups_m = [(k, np.flatnonzero((~is_if) & (layer == k))) for k in range(N - 1)]
        single = sum(1 for _, p in groups_if + groups_m if p is None or p.size) == 1
        d_out = np.zeros((3, m))
        wgt = np.zeros((3, m))
        pdf_fwd = np.ones(m)
        pdf_rev = np.ones(m)
        delta = np.zeros(m, dtype=bool)
        arrival = None
        for l, pos in groups_if:
            if pos is not None and not pos.size:
                continue
            whole = single and (pos is None or pos.size == m)
            ker = stack.kernels[l].take(lane if whole else lane[pos])
            wi_g = w_in if whole else w_in[:, pos]
            if ker.framed:
                # Arriving at a normal-mapped interface: |⟨n, d⟩| / |cos d| (kernels.FramedKernel).
                if arrival is None:
                    arrival = np.ones(m)
                if whole:
                    arrival = ker.arrival(wi_g)
                else:
                    arrival[pos] = ker.arrival(wi_g)
            wo, w, pf, pr, dl = (ker.sample(wi_g, rng, record) if ker.generic else
                                 ker.sample(wi_g, rng, record, approx))
            if whole:
                d_out, wgt, pdf_fwd, pdf_rev, delta = wo, w, pf, pr, dl
            else:
                d_out[:, pos], wgt[:, pos], pdf_fwd[pos], pdf_rev[pos], delta[pos] = wo, w, pf, pr, dl
        for k, pos in groups_m:
            if not pos.size:
                continue
            phase = stack.slabs[k].phase.take(lane[pos])
            di = d_in[:, pos]
            ps = phase.sample(di.T, rng)
            do = np.ascontiguousarray(ps.d_out.T)
            d_out[:, pos] = do
            wgt[:, pos] = ps.weight
            pdf_fwd[pos] = ps.pdf
            if record:
                pdf_rev[pos] = phase.pdf(-ps.d_out, -di.T)
        beta = S["beta"] if arrival is None else S["beta"] * arrival
        thru1 = beta * wgt
        if record:
            rec = {"lane": lane, "k": np.full(m, i, dtype=np.int64), "kind": kind, "layer": layer,
                   "t": t, "w_in": w_in, "w_out": d_out, "pdf_fwd": pdf_fwd, "pdf_rev": pdf_rev,
                   "dens_fwd": S["dens_fwd"], "pdf_fwd_prev": S["c_pdf_fwd"], "delta": delta,
                   "delta_prev": S["c_delta"], "P": P}
            if want_value:
                rec["thru0"], rec["thru1"] = beta, thru1
            else:
                rec["gamma"], rec["Q"] = S["gamma"], Q
            chunks.append(rec)
            S["c_dens_fwd"], S["c_pdf_rev"] = S["dens_fwd"], pdf_rev
            S["c_pdf_fwd_prev"], S["c_delta_prev"] = S["c_pdf_fwd"], S["c_delta"]
            S["c_pdf_fwd"], S["c_delta"], S["c_P"], S["c_Q"] = pdf_fwd, delta, P, Q
        S["beta"] = beta = thru1
        S["all_delta"] = S["all_delta"] & delta & is_if
        # ---------------------------------------------------------------- move
        up = d_out[2] > 0
        exits = is_if & ((up & (layer == 0)) | (~up & (layer == N - 1)))
        if exits.any():
            e = np.flatnonzero(exits)
            exit_dir[:, lane[e]] = d_out[:, e]
            exit_weight[:, lane[e]] = beta[:, e]
            exit_delta[lane[e]] = S["all_delta"][e]
        S["slab"] = np.where(is_if, np.where(up, layer - 1, layer), layer)
        S["up"] = up
        S["d_in"] = d_out
        bmax = beta.max(axis=0)
        alive = (~exits) & (np.abs(d_out[2]) >= GRAZING) & (bmax > 0)
        if i >= rr[0] and not approx:  # approximate-pdf walks are short and carry no values
            q = np.minimum(1.0, bmax / rr[1])
            # q below 1e-300 would overflow 1/q; such lanes are (almost surely) killed anyway.
            alive &= (rng.random(m) < q) & (q > 1e-300)
            inv_q = 1.0 / np.where(q > 1e-300, q, 1.0)
            S["beta"] = beta * inv_q
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
        dead = None
        for k in range(N - 1):
            kd = stack.kinds[k]
            if kd == EMPTY:
                continue
            pos = np.flatnonzero(slab == k) if N > 2 else None
            if pos is not None and not pos.size:
                continue
            whole = pos is None
            lk = lane if whole else lane[pos]
            dk = d if whole else d[:, pos]
            tk = t if whole else t[pos]
            if approx or kd == ABSORBING:
                tr = stack.transmittance(k, lk, dk, tk, new_t if whole else new_t[pos])
                if approx:
                    g = tr.mean(axis=0) if tr.ndim == 2 else tr
                    if whole:
                        gamma = gamma * g
                    else:
                        gamma[pos] = gamma[pos] * g
                else:
                    if whole:
                        beta = beta * tr
                    else:
                        beta[:, pos] = beta[:, pos] * tr
                continue
            ops = stack.slabs[k].take(lk)
            s0 = tk - k
            if ops.grey:
                new_s, sc, w, pdf, alive_k = ops.free_flight(s0, dk, rng)
            else:
                r_in = S["r"] if whole else S["r"][:, pos]
                new_s, sc, w, r_out, pdf, alive_k = ops.spectral_step(
                    s0, dk, rng, S["hero"] if whole else S["hero"][pos], r_in)
                if whole:
                    S["r"] = r_out
                else:
                    S["r"] = S["r"].copy()
                    S["r"][:, pos] = r_out
            lay = np.where(sc, k, new_layer if whole else new_layer[pos])
            if whole:
                beta = beta * w
                new_t = k + new_s
                new_kind = np.where(sc, 0, 1).astype(np.int8)
                new_layer = lay
                dens_fwd = pdf
            else:
                beta[:, pos] = beta[:, pos] * w
                new_t[pos] = k + new_s
                new_kind[pos] = np.where(sc, 0, 1)
                new_layer[pos] = lay
                dens_fwd[pos] = pdf
            if record:
                dr = ops.depth_pdf(-dk, new_s, s0, prev_medium if whole else prev_medium[pos])
                if whole:
                    dens_rev = dr
                else:
                    dens_rev[pos] = dr
        S["kind"], S["layer"], S["t"] = new_kind, new_layer, new_t
        if record:
            S["dens_fwd"], S["dens_rev"] = dens_fwd, dens_rev
        S["beta"], S["gamma"] = beta, gamma
        S = _compact(S, beta.max(axis=0) > 0)
        i += 1
    return WalkResult(exit_dir, exit_weight, exit_delta, Records(n, chunks) if record else None,
                      vertices, capped)
