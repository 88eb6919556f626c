"""Entry points of the layered BSDF: the integrator's per-lane call (``shade_lane``) and one batch
loop for NumPy callers (``run``: backend/layered/bsdf.py, i.e. the BSDF inspector and tests), both
over the same per-lane estimators (estimators.py).

Scratch (never allocated inside the kernels): ``W`` (2, capacity, walk.NF) float64 — the records
of a query's two walks; ``Bs`` (table.BSIZE,) — a textured stack bound at the lane's (u, v);
``R`` uint64[2] — the lane's walk stream (key, counter); ``C`` int64[4] — counters (walks,
vertices, walk-cap hits). One set per thread (per work item in the integrator).

Random numbers: the integrator's lane draws from ``hash(path key, bounce dimension SLOT_SPARE)``
(kernels/rng.py), so images do not depend on worker counts or batch sizes; a batch call with
``seed`` gives lane i the stream ``path_key(seed, i, 0)``.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from ..jit import kernel
from ..rng import SLOT_MIS_PDF, SLOT_SPARE, bounce_dim, path_key, stream_key
from . import estimators as es
from .table import BSIZE, H_EST, H_PDF, UNIT_DUV, bind_into

OP_EVAL, OP_PDF, OP_SAMPLE, OP_NEE, OP_ALBEDO = 0, 1, 2, 3, 4
CAPACITY = 4096      # recorded vertices per walk at most (min with the stack's max_vertices)


def scratch(max_vertices: int = 1024):
    """(W, Bs, R, C) for one thread."""
    cap = int(min(max(max_vertices, 2), CAPACITY))
    from .walk import NF
    return (np.zeros((2, cap, NF)), np.zeros(BSIZE), np.zeros(2, np.uint64), np.zeros(4, np.int64))


#: What the bounce loop asks of a layered lane (``shade_lane``), by name: the light connection
#: towards ``wo`` (``nee``) and its MIS pdf (``nee_pdf``), a continuation sample (``do_continue``)
#: and its MIS pdf now (``sample_pdf``; false: left for later, −1), or only that deferred pdf
#: (``pdf_only``); ``camera``: the lane's first hit (the albedo AOV).
LaneAsks = namedtuple("LaneAsks", ["nee", "nee_pdf", "do_continue", "sample_pdf", "pdf_only", "camera"])


@kernel
def shade_lane(ST, TX, s, u, v, duv, wi, wo, asks, key, segment, walk):
    """The layered part of one bounce of one lane (RADIANCE transport): (f, pdf of the light
    direction, continuation wo, weight, pdf, delta, albedo AOV estimate). ``asks``: a LaneAsks.
    At a camera hit the AOV is the continuation's reflected weight (it averages to the
    directional albedo at the viewing angle, delta lobes included, at no extra cost), else a
    one-sample normal-incidence walk. ``duv``: the surface's dP/du and dP/dv in the lane's
    shading frame (the interfaces' bump maps; table.H_BUMP). A deferred pdf (``asks.pdf_only``)
    is the one of the continuation ``wo`` this lane sampled at ``segment`` (returned as the second
    value), from a sub-stream of its own (SLOT_MIS_PDF): independent of the walks that sampled
    wo, as an estimate made at the time would be. ``walk``: the thread's WalkScratch
    (kernels/workitems.py)."""
    nee, nee_pdf, do_continue, sample_pdf, pdf_only, camera = asks
    W, Bs, R, C = walk
    R[0] = stream_key(key, bounce_dim(segment, SLOT_MIS_PDF if pdf_only else SLOT_SPARE))
    R[1] = 0
    if ST.textured[s]:
        bind_into(ST, TX, s, u, v, duv, Bs)
        B = Bs
    else:
        B = ST.bound[s]
    FT = ST.FT
    f, p_nee, wo_s, w_s, p_s, d_s = es.nee_and_sample(B, FT, W, R, wi, wo, nee, nee_pdf, do_continue,
                                                      sample_pdf, pdf_only, C)
    alb = (0.0, 0.0, 0.0)
    if camera and not pdf_only:
        if do_continue:
            if wo_s[2] * wi[2] > 0.0:
                alb = w_s
        else:
            alb = es.albedo(B, FT, W, R, C)
    return f, p_nee, wo_s, w_s, p_s, d_s, alb


#: A query of ``run``: which (OP_*), the transport mode, the estimator and pdf kind (−1: the
#: stack's own), whether a sample's pdf, the light connection's pdf and the continuation sample
#: are wanted, and the seed of the lanes' random streams.
Query = namedtuple("Query", ["op", "mode", "est", "kind", "want_pdf", "nee_pdf", "want_sample", "seed"])
#: ``run``'s outputs, one row per lane: f, pdf, and the sample (direction, weight, pdf, delta).
Answers = namedtuple("Answers", ["f", "p", "wo_s", "w_s", "p_s", "d_s"])


@kernel(nogil=True)
def run(query, ST, TX, s, uv, wi, wo, nee, walk, out):
    """One query per lane i (``uv``, ``wi``, ``wo``, ``nee``: (1 | n) rows; ``out``: Answers of
    (n, ·) rows; ``walk``: a WalkScratch): OP_EVAL f = eval (``est`` −1: the stack's estimator);
    OP_PDF p = pdf (``kind`` −1: the stack's); OP_SAMPLE (wo_s, w_s, p_s, d_s) = sample; OP_NEE f, p
    (light connection) and the sample; OP_ALBEDO w_s = one-sample normal-incidence albedo."""
    op, mode, est, kind, want_pdf, nee_pdf, want_sample, seed = query
    W, Bs, R, C = walk
    f, p, wo_s, w_s, p_s, d_s = out
    n = f.shape[0]
    for i in range(n):
        a = i if uv.shape[0] > 1 else 0
        R[0] = path_key(seed, i, 0)
        R[1] = 0
        if ST.textured[s]:
            bind_into(ST, TX, s, uv[a, 0], uv[a, 1], UNIT_DUV, Bs)
            B = Bs
        else:
            B = ST.bound[s]
        FT = ST.FT
        x = (wi[i, 0], wi[i, 1], wi[i, 2])
        y = (wo[i if wo.shape[0] > 1 else 0, 0], wo[i if wo.shape[0] > 1 else 0, 1],
             wo[i if wo.shape[0] > 1 else 0, 2])
        e = est if est >= 0 else int(B[H_EST])
        k = kind if kind >= 0 else int(B[H_PDF])
        if op == OP_EVAL:
            r = es.eval_query(B, FT, W, R, x, y, mode, e, C)
            f[i, 0], f[i, 1], f[i, 2] = r
        elif op == OP_PDF:
            p[i] = es.pdf_query(B, FT, W, R, x, y, k, C)
        elif op == OP_SAMPLE:
            d, w, q, dl = es.sample_query(B, FT, W, R, x, mode, want_pdf, k, C)
            wo_s[i, 0], wo_s[i, 1], wo_s[i, 2] = d
            w_s[i, 0], w_s[i, 1], w_s[i, 2] = w
            p_s[i] = q
            d_s[i] = dl
        elif op == OP_NEE:
            r, q0, d, w, q, dl = es.nee_and_sample(B, FT, W, R, x, y, nee[i], nee_pdf, want_sample, True,
                                                   False, C)
            f[i, 0], f[i, 1], f[i, 2] = r
            p[i] = q0
            wo_s[i, 0], wo_s[i, 1], wo_s[i, 2] = d
            w_s[i, 0], w_s[i, 1], w_s[i, 2] = w
            p_s[i] = q
            d_s[i] = dl
        else:
            w = es.albedo(B, FT, W, R, C)
            w_s[i, 0], w_s[i, 1], w_s[i, 2] = w
