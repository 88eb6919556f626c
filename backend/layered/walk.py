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
  thru0, thru1  throughput arriving at the vertex / after its sampled direction (RGB; "value")
  pdf_fwd       density of w_out given w_in (1 for delta samples: a placeholder, see connect.py)
  delta         the sampled direction came from a delta lobe
  c1, c2, A, B  the vertex's MIS coefficients for the bidirectional connections (connect.Side)
  gamma, qbg, rev   for the pdf estimator ("pdf"): the walk's weight in the pdf integrand
                (1/survival probabilities and, for the approximate pdf, slab pass probabilities),
                and its products with the running pdf ratios (connect.Side)

MIS recurrences (the paper's appendix B, folded): with inv_dens = 1/dens_fwd (0 for the first
vertex), own = ¬δ, ipf = 1/pdf_fwd and dens_rev the reverse density of the previous vertex's
depth along the edge into this one, vertex i has
    a_i  = (own_{i−1} + dens_rev_i·b1_{i−1})·ipf_{i−1},   b1_i = inv_dens_i·(own_i + pdf_rev_i·a_i),
    qb_i = inv_dens_i·dens_rev_i·pdf_rev_{i−1}·qb_{i−1}·ipf_{i−1}   (qb_1 = 1),
so the walk carries only the previous vertex's own, b1, ipf (and pdf_rev, qb).

Directional media (microflake phases): the extinction scale s(d) of the current direction is
computed once (by the phase sampler, or on entering a slab) and reused for the free flight, its
reverse density and the next phase sample.

Termination: unbiased Russian roulette on the throughput (``rr``), and a hard cap
``max_vertices`` whose hits are counted (``WalkResult.capped``) — never silent.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .stack import ABSORBING, EMPTY, GRAZING, SCATTERING, BoundStack

# Russian roulette: after vertex ``start`` a walk survives with probability
# min(1, max channel of throughput / threshold). Walks feeding the estimators (eval, pdf) use an
# aggressive setting: their connection cost grows with the square of the walk length while the
# variance barely changes (measured: Fig. 2 stack, 3x faster at +3 % variance). Walks that
# *are* the sample (``sample``) keep a mild one: their weight goes straight into the image.
RR_EVAL = (2, 1.0)
RR_SAMPLE = (4, 0.25)
RR_OFF = (1 << 62, 1.0)
BIG = 1e300      # clamp of the MIS coefficients: no 0·∞ in the connection weights

# Tests set this to also record the unfolded MIS quantities (P, Q, densities) that the
# pair-list reference implementation (tests/layered_bidir_reference.py) reads.
LEGACY_FIELDS = False


class Records:
    """Struct of arrays, one entry (column for vectors) per vertex, in the order the walk made
    them (iteration-major). ``perm`` lists the entries lane by lane: lane l's vertices, in walk
    order, are ``perm[offset[l] : offset[l] + count[l]]`` (no re-sorting of every field); ``bounds`` =
    offset with the total appended."""

    def __init__(self, n: int, chunks: list[dict]):
        self.n = n
        keys = chunks[0].keys() if chunks else ("lane", "k")
        for f in keys:
            v = [c[f] for c in chunks]
            setattr(self, f, np.concatenate(v, axis=-1) if v else np.zeros(0, dtype=np.int64))
        lane = self.lane
        self.count = np.bincount(lane, minlength=n).astype(np.int64)
        self.bounds = np.concatenate([[0], np.cumsum(self.count)]).astype(np.int64)
        self.offset = self.bounds[:-1]
        self.perm = np.empty(lane.size, dtype=np.int64)
        self.perm[self.offset[lane] + self.k - 1] = np.arange(lane.size)
        self.size = lane.size


def _inv(x):
    ok = x > 0
    return np.where(ok, 1.0 / np.where(ok, x, 1.0), 0.0)


@dataclass
class WalkResult:
    exit_dir: np.ndarray     # (3, n) direction the walk left the stack (0 if it did not)
    exit_weight: np.ndarray  # (3, n) throughput after the exit vertex (0 if it did not exit)
    exit_delta: np.ndarray   # (n,) every vertex of the path was a delta sample
    records: Records | None
    vertices: int            # total vertices made
    capped: int              # walks stopped by the vertex cap (biased energy loss, reported)
    hero: np.ndarray | None = None  # (n,) each walk's hero channel (chromatic media), else None


def _compact(S: dict, keep: np.ndarray) -> dict:
    if keep.all():
        return S
    sel = np.flatnonzero(keep)
    return {k: (v if v is None else np.take(v, sel, axis=-1)) for k, v in S.items()}


def _groups(kind, layer, N):
    """[(is_interface, index, positions or None for all)] of the lanes' vertex kinds."""
    is_if = kind == 1
    if N == 1:
        return [(True, 0, None)]
    out = []
    n_if = int(np.count_nonzero(is_if))
    if n_if:
        for l in range(N):
            out.append((True, l, np.flatnonzero(is_if & (layer == l))))
    if n_if < kind.size:
        for k in range(N - 1):
            out.append((False, k, np.flatnonzero(~is_if & (layer == k))))
    out = [g for g in out if g[2].size]
    if len(out) == 1:
        out = [(out[0][0], out[0][1], None)]
    return out


def walk(stack: BoundStack, w0: np.ndarray, rng: np.random.Generator, record: bool = True,
         approx: bool = False, max_vertices: int = 1024, rr: tuple = RR_EVAL,
         purpose: str = "value", hero: np.ndarray | None = None) -> WalkResult:
    """Walk from direction ``w0`` ((3, n), pointing away from the surface): enter at the top if
    w0_z > 0, else at the bottom. ``approx``: media do not scatter (crossing a slab multiplies
    ``gamma`` by its pass probability), for the approximate pdf. ``purpose`` selects the recorded
    fields: "value" (throughputs, for eval) or "pdf" (for the pdf).

    Chromatic extinction: each walk samples its free flights with one hero channel (``hero``
    (n,) if given, else drawn here; returned in ``WalkResult.hero``). Value walks weight the
    channels with path-level spectral MIS (slab.py) and record channel-mean depth densities. A
    stochastic-pdf walk ("pdf", not ``approx``) estimates the density of that sampler, which is
    the channel average of the *path* densities of the single-channel samplers (not a product
    of per-event channel means): it records the hero channel's depth densities, and both walks
    of a query must share the hero (connect.bidirectional ``hero``), so that the estimate is the
    hero channel's path density, averaged over the uniformly drawn hero."""
    want_value = purpose == "value"
    n = w0.shape[1]
    N = stack.N
    exit_dir = np.zeros((3, n))
    exit_weight = np.zeros((3, n))
    exit_delta = np.zeros(n, dtype=bool)
    chunks: list[dict] = []

    start = np.flatnonzero(w0[2] != 0)   # a start direction in the surface plane cannot enter
    m = start.size
    layer0 = np.where(w0[2, start] > 0, 0, N - 1).astype(np.int64)
    S = {"lane": start, "kind": np.ones(m, dtype=np.int8), "layer": layer0,
         "t": layer0.astype(np.float64), "d": -np.take(w0, start, axis=1), "beta": np.ones((3, m)),
         "gamma": np.ones(m), "all_delta": np.ones(m, dtype=bool), "sig": None}
    if record:
        S.update({"dens_f": np.ones(m), "dens_r": np.ones(m), "own_p": np.zeros(m),
                  "b1_p": np.zeros(m), "ipf_p": np.zeros(m)})
        if not want_value or LEGACY_FIELDS:
            S.update({"qb_p": np.ones(m), "pr_p": np.zeros(m)})
        if LEGACY_FIELDS:
            S.update({"pf_p": np.ones(m), "dl_p": np.zeros(m, dtype=bool), "P_p": np.zeros(m)})
    directional = [sl is not None and sl.directional for sl in stack.slabs]
    if any(directional):
        S["sig"] = np.ones(m)
    chromatic = any(sl is not None and not sl.grey and k == SCATTERING
                    for sl, k in zip(stack.slabs, stack.kinds)) and not approx
    hero_pdf = chromatic and not want_value
    hero_all = None
    if chromatic:
        # Path-level spectral MIS (slab.py): one hero channel per walk, density ratios r.
        if hero is None:
            hero_all = np.zeros(n, dtype=np.int64)
            hero_all[start] = np.minimum((rng.random(m) * 3.0).astype(np.int64), 2)
        else:
            hero_all = np.asarray(hero, dtype=np.int64)
        S["hero"] = hero_all[start]
        if not hero_pdf:
            S["r"] = np.ones((3, m))

    vertices = 0
    capped = 0
    i = 1
    while S["lane"].size:
        lane, kind, layer, d = S["lane"], S["kind"], S["layer"], S["d"]
        m = lane.size
        vertices += m
        w_in = -d
        is_if = kind == 1
        # ---------------------------------------------------------------- sample the vertex
        groups = _groups(kind, layer, N)
        whole = groups[0][2] is None
        if not whole:
            d_out = np.zeros((3, m))
            wgt = np.zeros((3, m))
            pdf_fwd = np.ones(m)
            pdf_rev = np.ones(m)
            delta = np.zeros(m, dtype=bool)
            sig_new = None if S["sig"] is None else S["sig"].copy()
        arrival = None
        for g_if, l, pos in groups:
            lk = lane if pos is None else lane[pos]
            wi_g = w_in if pos is None else np.take(w_in, pos, axis=1)
            if g_if:
                ker = stack.kernels[l].take(lk)
                if ker.framed:
                    # Arriving at a normal-mapped interface: |⟨n, d⟩| / |cos d| (kernels.FramedKernel).
                    arr = ker.arrival(wi_g)
                    if pos is None:
                        arrival = arr
                    else:
                        if arrival is None:
                            arrival = np.ones(m)
                        arrival[pos] = arr
                out = (ker.sample(wi_g, rng, record) if ker.generic else
                       ker.sample(wi_g, rng, record, approx))
                sg = None
            else:
                phase = stack.slabs[l].phase.take(lk)
                s_in = None
                if directional[l]:
                    s_in = S["sig"] if pos is None else S["sig"][pos]
                do, w1, pf, pr, sg = phase.sample3(-wi_g, rng, s_in)
                out = (do, w1, pf, pr, np.zeros(do.shape[1], dtype=bool))
            if pos is None:
                d_out, wgt, pdf_fwd, pdf_rev, delta = out
                if wgt.ndim == 1:
                    wgt = wgt[None, :]
                sig_new = sg if sg is not None else S["sig"]
            else:
                d_out[:, pos], wgt[:, pos] = out[0], out[1]
                pdf_fwd[pos], pdf_rev[pos], delta[pos] = out[2], out[3], out[4]
                if sg is not None:
                    sig_new[pos] = sg
        beta = S["beta"] if arrival is None else S["beta"] * arrival
        thru1 = beta * wgt
        if record:
            first = i == 1
            inv_dens = np.zeros(m) if first else _inv(S["dens_f"])
            P = S["dens_r"] * S["b1_p"]
            a = (S["own_p"] + P) * S["ipf_p"]
            own = (~delta) * 1.0
            ipf = _inv(pdf_fwd)
            b1 = inv_dens * (own + pdf_rev * a)
            rec = {"lane": lane, "k": np.full(m, i, dtype=np.int64), "kind": kind, "layer": layer,
                   "t": S["t"], "w_in": w_in, "w_out": d_out, "pdf_fwd": pdf_fwd, "delta": delta,
                   "c1": np.minimum(inv_dens, BIG), "c2": np.minimum(inv_dens * a, BIG),
                   "A": np.minimum(ipf * own, BIG), "B": np.minimum(ipf * b1, BIG)}
            if want_value:
                rec["thru0"], rec["thru1"] = beta, thru1
            if sig_new is not None:
                # Extinction scales for the connections (read at medium vertices only, whose
                # entries no later in-place update changes): σ(w_in) and σ(w_out).
                rec["sig_in"], rec["sig_out"] = S["sig"], sig_new
            if not want_value or LEGACY_FIELDS:
                qb = np.ones(m) if first else inv_dens * S["dens_r"] * S["pr_p"] * S["qb_p"] * S["ipf_p"]
                gamma = S["gamma"]
                if not want_value:
                    rec["gamma"], rec["qbg"] = gamma, qb * gamma
                    rec["rev"] = ipf * pdf_rev * qb * gamma
            if LEGACY_FIELDS:
                rec.update({"pdf_rev": pdf_rev, "dens_fwd": S["dens_f"], "pdf_fwd_prev": S["pf_p"],
                            "delta_prev": S["dl_p"], "P": P, "gamma": S["gamma"],
                            "Q": np.zeros(m) if first else S["dens_r"] * S["pr_p"] * S["qb_p"]})
                S["pf_p"], S["dl_p"] = pdf_fwd, delta
            chunks.append(rec)
            S["own_p"], S["b1_p"], S["ipf_p"] = own, b1, ipf
            if not want_value or LEGACY_FIELDS:
                S["qb_p"], S["pr_p"] = qb, pdf_rev
        S["beta"] = beta = thru1
        S["all_delta"] = S["all_delta"] & delta & is_if
        S["sig"] = sig_new
        # ---------------------------------------------------------------- move
        up = d_out[2] > 0
        exits = is_if & ((up & (layer == 0)) | (~up & (layer == N - 1)))
        if exits.any():
            e = np.flatnonzero(exits)
            le = lane[e]
            exit_dir[:, le] = np.take(d_out, e, axis=1)
            exit_weight[:, le] = np.take(beta, e, axis=1)
            exit_delta[le] = S["all_delta"][e]
        S["prev_medium"] = ~is_if
        S["slab"] = np.where(is_if, np.where(up, layer - 1, layer), layer)
        S["up"] = up
        S["d"] = d_out
        bmax = np.maximum(np.maximum(beta[0], beta[1]), beta[2])
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
        _flights(stack, S, rng, record, approx, directional, hero_pdf)
        S = _compact(S, np.maximum(np.maximum(S["beta"][0], S["beta"][1]), S["beta"][2]) > 0)
        i += 1
    return WalkResult(exit_dir, exit_weight, exit_delta, Records(n, chunks) if record else None,
                      vertices, capped, hero_all)


def _flights(stack, S, rng, record, approx, directional, hero_pdf=False):
    """Move every lane through the slab its direction enters: to the interface ahead, or to a
    scattering vertex inside a scattering medium. Updates S in place (kind, layer, t, beta,
    gamma, densities of the new edge, the direction's extinction scale)."""
    N = stack.N
    lane, t, d, slab, up = S["lane"], S["t"], S["d"], S["slab"], S["up"]
    m = lane.size
    new_layer = np.where(up, slab, slab + 1)
    new_kind = np.ones(m, dtype=np.int8)
    new_t = new_layer.astype(np.float64)
    dens_f = np.ones(m)
    dens_r = np.ones(m)
    beta, gamma = S["beta"], S["gamma"]
    copied = sig_copied = False
    for k in range(N - 1):
        kd = stack.kinds[k]
        if kd == EMPTY:
            continue
        pos = np.flatnonzero(slab == k) if N > 2 else None
        if pos is not None and not pos.size:
            continue
        whole = pos is None
        if not whole and not copied:
            # Copies: the record chunks share these arrays.
            beta, gamma = beta.copy(), gamma.copy()
            copied = True
        lk = lane if whole else lane[pos]
        dk = d if whole else np.take(d, pos, axis=1)
        s0 = (t if whole else t[pos]) - k
        ops = stack.slabs[k].take(lk)
        az = np.abs(dk[2])
        alive = az >= GRAZING
        inv = 1.0 / np.where(alive, az, 1.0)
        if directional[k]:
            # Extinction scale of the direction: reuse the phase sampler's value after a medium
            # vertex of this slab; compute it on entering the slab from an interface.
            sig = S["sig"] if whole else S["sig"][pos]
            pm = S["prev_medium"] if whole else S["prev_medium"][pos]
            if not pm.all():
                fresh = np.flatnonzero(~pm)
                sig = sig.copy()
                sig[fresh] = ops.phase.take(fresh).sigma3(np.take(dk, fresh, axis=1))
            inv = inv * sig
            if whole:
                S["sig"] = sig
            else:
                if not sig_copied:
                    # A copy: the record chunks share S["sig"] (connections read it).
                    S["sig"] = S["sig"].copy()
                    sig_copied = True
                S["sig"][pos] = sig
        rate = ops.tau[0] * inv if ops.grey else ops.tau * inv
        dmax = np.maximum(np.where(dk[2] > 0, s0, 1.0 - s0), 0.0)
        if approx or kd == ABSORBING:
            e = np.where(alive, np.exp(-rate * dmax), 0.0)
            if approx:
                g = e.mean(axis=0) if e.ndim == 2 else e
                if whole:
                    gamma = gamma * g
                else:
                    gamma[pos] = gamma[pos] * g
            elif whole:
                beta = beta * e
            else:
                beta[:, pos] = beta[:, pos] * e
            continue
        pm = S["prev_medium"] if whole else S["prev_medium"][pos]
        hero_flight = hero_pdf and not ops.grey
        if hero_flight:
            # A stochastic-pdf walk (see ``walk``): the hero channel's single-channel walk. Its
            # throughput is not needed (pdf walks carry no values); only failures end it.
            hero = S["hero"] if whole else S["hero"][pos]
            rate = np.take_along_axis(rate, hero[None, :], axis=0)[0]
        if hero_flight or ops.grey:
            u = rng.random(lk.size)
            with np.errstate(divide="ignore"):
                step = -np.log1p(-u) / rate
            sc = (step < dmax) & alive
            step = np.where(sc, step, dmax)
            ex = np.exp(-rate * step)
            dens = np.where(alive, np.where(sc, rate * ex, ex), 0.0)
            w = alive * 1.0 if hero_flight else np.where(alive, np.where(sc, ops.albedo, 1.0), 0.0)
            drev = np.where(alive, np.where(pm, rate * ex, ex), 0.0) if record else None
        else:
            hero = S["hero"] if whole else S["hero"][pos]
            r_in = S["r"] if whole else np.take(S["r"], pos, axis=1)
            step, sc, w, r_out, dens, drev = ops.spectral_flight(s0, dk, rng, hero, r_in, rate, alive,
                                                                 dmax, pm if record else None)
            if whole:
                S["r"] = r_out
            else:
                S["r"] = S["r"].copy()
                S["r"][:, pos] = r_out
        new_s = np.where(sc, np.where(dk[2] > 0, s0 - step, s0 + step), np.where(dk[2] > 0, 0.0, 1.0))
        if whole:
            beta = beta * w
            new_t = np.where(sc, k + new_s, new_t)
            new_kind = np.where(sc, 0, 1).astype(np.int8)
            new_layer = np.where(sc, k, new_layer)
            dens_f = dens
            if record:
                dens_r = drev
        else:
            beta[:, pos] = beta[:, pos] * w
            new_t[pos] = np.where(sc, k + new_s, new_t[pos])
            new_kind[pos] = np.where(sc, 0, 1)
            new_layer[pos] = np.where(sc, k, new_layer[pos])
            dens_f[pos] = dens
            if record:
                dens_r[pos] = drev
    S["kind"], S["layer"], S["t"] = new_kind, new_layer, new_t
    if record:
        S["dens_f"], S["dens_r"] = dens_f, dens_r
    S["beta"], S["gamma"] = beta, gamma
