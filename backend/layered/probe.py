"""Inspection of the compiled layered code from NumPy (tests, the BSDF inspector's debugging): the
bound stack of a lane, one interface's sample/eval with both densities, slab transmittance and
depth densities, whole walks with their MIS records, and the bidirectional sums of given walks.
Everything calls the per-lane code the renderer runs (backend/kernels/layered/probe.py)."""
from __future__ import annotations

import numpy as np

from ..kernels.layered import iface as ki
from ..kernels.layered import phase as kp
from ..kernels.layered import table as kt
from ..kernels.layered import walk as kw
from .phase.base import draw_seed

IFACE_KINDS = {0: "diffuse", 1: "conductor", 2: "dielectric", ki.NULL: "null"}
SLAB_KINDS = {kt.EMPTY: "empty", kt.ABSORBING: "absorbing", kt.SCATTERING: "scattering"}
PHASE_NAMES = {v: k for k, v in kp.KINDS.items()}


def _rows3(x):
    return np.ascontiguousarray(np.asarray(x, dtype=np.float64).reshape(-1, 3))


# ----------------------------------------------------------------------------- interfaces
def interface_block(material, normal=None, uv=None) -> np.ndarray:
    """(m, iface.STRIDE) bound blocks of one interface material (a standard material's ``pack``)
    with an optional shading normal (3,), at ``uv`` ((m, 2), default one constant lane)."""
    from ..kernels import materials as km
    from ..kernels.layered.probe import bind_iface_rows
    from ..kernels.params import ParamPacker
    packer = ParamPacker()
    row = km.MaterialRow(packer)
    material.pack(row)
    tx = packer.table()
    uv = np.zeros((1, 2)) if uv is None else np.ascontiguousarray(uv, dtype=np.float64)
    nval = np.zeros(3)
    mode = 0
    if normal is not None:
        nval = np.asarray(normal, dtype=np.float64).reshape(3)
        nval = nval / np.linalg.norm(nval)
        mode = 1
    B = np.zeros((uv.shape[0], ki.STRIDE))
    bind_iface_rows(row.kind, row.dist, row.masking, row.values[None, :].copy(), row.tex[None, :].copy(),
                    mode, nval, -1, tx, uv, B)
    return B


def iface_eval(block, wi, wo):
    """(value f·|cos θo| (n, 3) importance transport, pf (n,), pr (n,))."""
    from ..kernels.layered.probe import iface_eval as run
    wi, wo = _rows3(wi), _rows3(wo)
    n = wi.shape[0]
    val, pf, pr = np.empty((n, 3)), np.empty(n), np.empty(n)
    run(np.ascontiguousarray(block), wi, wo, val, pf, pr)
    return val, pf, pr


def iface_sample(block, wi, rng):
    """(wo, weight, pf, pr, delta) of the walk's interface sampler (importance transport)."""
    from ..kernels.layered.probe import iface_sample as run
    wi = _rows3(wi)
    n = wi.shape[0]
    wo, w, pf, pr, delta = np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n), np.empty(n, bool)
    run(np.ascontiguousarray(block), wi, draw_seed(rng), np.zeros(2, np.uint64), wo, w, pf, pr, delta)
    return wo, w, pf, pr, delta


# ----------------------------------------------------------------------------- bound stacks
def bound_blocks(bsdf, lanes=None) -> np.ndarray:
    """(m, table.BSIZE): the bound stack of a LayeredBSDF's lanes (all, or ``lanes``)."""
    from ..kernels.layered.probe import bound_blocks as run
    ST, TX, s = bsdf.material.kernel_table()
    uv = bsdf.uv if lanes is None or bsdf.uv.shape[0] == 1 else bsdf.uv[np.asarray(lanes)]
    out = np.zeros((uv.shape[0], kt.BSIZE))
    run(ST, TX, s, np.ascontiguousarray(uv), out)
    return out


def describe(bsdf, lane: int = 0) -> dict:
    """A lane's bound stack, decoded: interfaces (kind, relative index or conductor eta/k, delta,
    normal map) and media (kind, optical depth, albedo, phase, directional)."""
    B = bound_blocks(bsdf, [lane])[0]
    N = int(B[kt.H_N])
    out = {"N": N, "transmissive": bool(B[kt.H_TRANS]), "eta_top": B[kt.H_ETA_TOP],
           "eta_bottom": B[kt.H_ETA_BOTTOM], "eta_slab": B[kt.H_ETA_SLAB:kt.H_ETA_SLAB + N - 1].tolist(),
           "interfaces": [], "media": []}
    for l in range(N):
        o = kt.HEAD + l * ki.STRIDE
        kind = IFACE_KINDS[int(B[o + ki.IF_KIND])]
        p = B[o + ki.IF_P:o + ki.IF_P + 12]
        d = {"kind": kind, "delta": bool(B[o + ki.IF_DELTA]), "framed": bool(B[o + ki.IF_FRAMED]),
             "normal": B[o + ki.IF_N:o + ki.IF_N + 3].copy() if B[o + ki.IF_FRAMED] else None}
        if kind == "dielectric":
            d.update(eta=p[0], tint=p[1:4].copy(), alpha=(p[4], p[5]))
        elif kind == "conductor":
            d.update(eta=p[0:3].copy(), k=p[3:6].copy(), tint=p[6:9].copy(), alpha=(p[9], p[10]))
        elif kind == "diffuse":
            d.update(color=p[0:3].copy())
        else:
            d.update(tint=p[0:3].copy())
        out["interfaces"].append(d)
    for k in range(N - 1):
        o = kt.MED0 + k * kt.MSTRIDE
        out["media"].append({"kind": SLAB_KINDS[int(B[o + kt.M_KIND])], "grey": bool(B[o + kt.M_GREY]),
                             "tau": B[o + kt.M_TAU:o + kt.M_TAU + 3].copy(),
                             "albedo": B[o + kt.M_ALB:o + kt.M_ALB + 3].copy(),
                             "phase": PHASE_NAMES[int(B[o + kt.M_PH + kp.PK])],
                             "directional": bool(B[o + kt.M_DIR])})
    return out


# ----------------------------------------------------------------------------- slabs
def slab_transmittance(bsdf, k, d, t0, t1):
    """(n, 3) transmittance in slab k from depth t0 to t1 along d (depths: slab k spans k … k + 1)."""
    from ..kernels.layered.probe import slab_transmittance as run
    d = _rows3(d)
    B = bound_blocks(bsdf)
    out = np.empty((d.shape[0], 3))
    run(B, bsdf.material.kernel_table()[0].FT, int(k), d, np.broadcast_to(np.asarray(t0, float), d.shape[:1]).copy(),
        np.broadcast_to(np.asarray(t1, float), d.shape[:1]).copy(), out)
    return out


def slab_depth_density(bsdf, k, d, t0, t1, to_medium, hero=None):
    from ..kernels.layered.probe import slab_depth_density as run
    d = _rows3(d)
    n = d.shape[0]
    B = bound_blocks(bsdf)
    out = np.empty(n)
    h = np.full(n, -1, np.int64) if hero is None else np.ascontiguousarray(hero, dtype=np.int64)
    run(B, bsdf.material.kernel_table()[0].FT, int(k), d, np.broadcast_to(np.asarray(t0, float), (n,)).copy(),
        np.broadcast_to(np.asarray(t1, float), (n,)).copy(),
        np.broadcast_to(np.asarray(to_medium, bool), (n,)).copy(), h, out)
    return out


# ----------------------------------------------------------------------------- walks
FIELDS = {"kind": kw.F_KIND, "layer": kw.F_LAYER, "t": kw.F_T, "pdf_fwd": kw.F_PF, "delta": kw.F_DELTA,
          "c1": kw.F_C1, "c2": kw.F_C2, "A": kw.F_A, "B": kw.F_B, "sig_in": kw.F_SIGIN,
          "sig_out": kw.F_SIGOUT, "gamma": kw.F_GAMMA, "qbg": kw.F_QBG, "rev": kw.F_REV,
          "pdf_rev": kw.F_PR, "dens_fwd": kw.F_DF, "dens_rev": kw.F_DR, "P": kw.F_P, "Q": kw.F_Q}
VECTORS = {"w_in": kw.F_WIN, "w_out": kw.F_WOUT, "thru0": kw.F_THRU0, "thru1": kw.F_THRU1}
PURPOSES = {"none": kw.NONE, "value": kw.VALUE, "pdf": kw.PDF}
RR = {"eval": (kw.RR_EVAL_START, kw.RR_EVAL_THR), "sample": (kw.RR_SAMPLE_START, kw.RR_SAMPLE_THR),
      "off": (kw.RR_OFF, 1.0)}


class Walks:
    """The walks of ``walks``: per lane ``count`` vertices, exit direction/weight/delta, hero, and
    the records (fields above) flattened lane-major: entry e is vertex ``k[e]`` (1-based) of lane
    ``lane[e]``; vectors are (3, m) (the layout of the former NumPy walk's records)."""

    def __init__(self, n, count, exit_dir, exit_weight, exit_delta, hero, rec, capped, purpose):
        self.n = n
        self.purpose = purpose
        self.count = count
        self.exit_dir, self.exit_weight, self.exit_delta = exit_dir, exit_weight, exit_delta
        self.hero = hero
        self.capped = capped
        self.raw = rec
        self.bounds = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
        self.offset = self.bounds[:-1]
        recorded = count if rec.shape[1] else np.zeros(n, np.int64)
        sel = np.arange(rec.shape[1])[None, :] < recorded[:, None]
        flat = rec[sel]
        self.lane = np.repeat(np.arange(n), recorded)
        self.k = (np.arange(flat.shape[0]) - np.repeat(np.cumsum(recorded) - recorded, recorded)) + 1
        self.size = flat.shape[0]
        self.perm = np.arange(self.size)
        for name, f in FIELDS.items():
            setattr(self, name, flat[:, f].copy())
        self.kind = self.kind.astype(np.int8)
        self.layer = self.layer.astype(np.int64)
        self.delta = self.delta > 0
        for name, f in VECTORS.items():
            setattr(self, name, np.ascontiguousarray(flat[:, f:f + 3].T))


def walks(bsdf, w0, rng, purpose="value", approx=False, rr="eval", cap=None, hero=None) -> Walks:
    """One walk per lane from directions ``w0`` (n, 3) through the bound stacks of ``bsdf``'s lanes."""
    from ..kernels.layered.probe import WalkOut, WalkSpec, walks as run
    w0 = _rows3(w0)
    n = w0.shape[0]
    ST, TX, s = bsdf.material.kernel_table()
    B = bound_blocks(bsdf)
    cap = int(cap if cap is not None else bsdf.options.max_vertices)
    width = cap if purpose != "none" else 1
    W1 = np.zeros((1, max(width, 1), kw.NF))
    count = np.zeros(n, np.int64)
    ed, ew, edl = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, bool)
    h = np.full(n, -1, np.int64) if hero is None else np.ascontiguousarray(hero, dtype=np.int64)
    hout = np.zeros(n, np.int64)
    rec = np.zeros((n, width if purpose != "none" else 0, kw.NF))
    C = np.zeros(4, np.int64)
    start, thr = RR[rr]
    run(B, ST.FT, w0, draw_seed(rng), WalkSpec(PURPOSES[purpose], bool(approx), int(start), float(thr), cap), h, W1,
        np.zeros(2, np.uint64), C, WalkOut(count, ed, ew, edl, hout, rec))
    return Walks(n, count, ed, ew, edl, hout, rec, int(C[0]), purpose)


def connect(bsdf, wo, L: Walks, R: Walks, pdf_mode=False, approx=False, nmax=None, hero=None):
    """The bidirectional sums (estimators.bidirectional) of given walks: (3, n) values without the
    final cosine, the single-interface term and any mode factor, or (n,) the pdf."""
    from ..kernels.layered.probe import connect as run
    wo = _rows3(wo)
    n = wo.shape[0]
    ST, TX, s = bsdf.material.kernel_table()
    B = bound_blocks(bsdf)
    width = max(L.raw.shape[1], R.raw.shape[1], 1)
    W2 = np.zeros((2, width, kw.NF))
    out3, outp = np.zeros((n, 3)), np.zeros(n)
    nm = np.zeros(n, np.int64) if nmax is None else np.ascontiguousarray(nmax, dtype=np.int64)
    h = np.full(n, -1, np.int64) if hero is None else np.ascontiguousarray(hero, dtype=np.int64)
    run(B, ST.FT, L.raw, L.count, R.raw, R.count, wo, bool(pdf_mode), bool(approx), nm, h, W2, out3, outp)
    return outp if pdf_mode else np.ascontiguousarray(out3.T)


def eval_at(bsdf, kind, layer, lane, w_in, w, pdf_only=False):
    """Vertex functions of walk vertices (kind 1 interface / 0 medium, layer, lane of ``bsdf``),
    incoming ``w_in`` and outgoing ``w`` ((3, m) each): (value (3, m), pf (m,), pr (m,))."""
    from ..kernels.layered.probe import vertex_eval as run
    w_in = np.ascontiguousarray(np.asarray(w_in, dtype=np.float64).T)
    w = np.ascontiguousarray(np.asarray(w, dtype=np.float64).T)
    m = w.shape[0]
    B = bound_blocks(bsdf)
    val, pf, pr = np.zeros((m, 3)), np.zeros(m), np.zeros(m)
    run(B, bsdf.material.kernel_table()[0].FT, np.ascontiguousarray(kind, dtype=np.int64),
        np.ascontiguousarray(layer, dtype=np.int64), np.ascontiguousarray(lane, dtype=np.int64),
        w_in, w, bool(pdf_only), val, pf, pr)
    return np.ascontiguousarray(val.T), pf, pr


def slab_flights(bsdf, k, s0, d, rng, hero=None):
    """One free flight per lane in slab k: (new normalised depth, scattered, weight (n, 3),
    density of the event) — the walk's own free flight."""
    from ..kernels.layered.probe import slab_flights as run
    d = _rows3(d)
    n = d.shape[0]
    B = bound_blocks(bsdf)
    h = (rng.integers(0, 3, n) if hero is None else np.asarray(hero)).astype(np.int64)
    out = (np.zeros(n), np.zeros(n, bool), np.zeros((n, 3)), np.zeros(n))
    run(B, bsdf.material.kernel_table()[0].FT, int(k), np.broadcast_to(np.asarray(s0, float), (n,)).copy(),
        d, h, draw_seed(rng), np.zeros(2, np.uint64), *out)
    return out


def layered_with_medium(spec, top=None, bottom=None):
    """A two-interface stack around one medium (null interfaces by default), for probing a slab."""
    from .bsdf import Options
    from .material import LayeredMaterial
    from .stack import NullMaterial
    top = top if top is not None else NullMaterial()
    bottom = bottom if bottom is not None else NullMaterial()
    return LayeredMaterial([top, bottom], [spec], [1.0], 1.0, Options())
