"""How far issue 3's throughput goal is from what the vertex functions alone cost in NumPy.

Context: issue 3 asks for ≥ 10× the per-core throughput of the authors' C++ code, i.e. a
bidirectional eval in ≤ 4.5 µs (one slab) and ≤ 11 µs (two microflake slabs), a sample in
≤ 1.0 / ≤ 2.3 µs (their sample: 10–23 µs). This script splits one bidirectional eval of each
benchmark stack (benchmarks/layered_throughput.py) into the work no implementation of the
estimator can skip, and prices that work with the project's own fused NumPy kernels:

* per eval: the number of connections by the kind of vertex they evaluate (an interface's
  BSDF with both densities, or a medium's phase function with its reverse density), counted on
  a real eval of 65 536 lanes; every connection must evaluate that vertex function once;
* per kind: the CPU time of one such evaluation, measured on blocks of 16 384 random direction
  pairs (the block size of the connection engine, cache-resident), with the masking terms
  precomputed (as the engine does) — arithmetic only: no gathers, no MIS, no accumulation;
* per walk vertex: the CPU time of one interface sample or one phase sample with its densities
  (the walk's vertex work, without free flights, roulette, records or compaction), times the
  vertices of each kind per walk (counted on real walks with the eval's and the sample's roulette).

The eval floor is the connections' vertex functions plus the vertex sampling of the two walks
(from wi and from wo); the sample floor is one walk's vertex sampling. They bound this
estimator's cost per lane from below for any NumPy implementation that uses kernels of this
cost: the real eval adds free flights, records, gathers, MIS weights and accumulation. The
timings are CPU times of one process; on a shared VM they move by ±20–50 % with the
neighbours' load, floor and measured figures alike, so compare them within one run.

    .venv/bin/python -m benchmarks.layered_floor [--lanes 65536] [--block 16384] [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402  (after the backend package: one BLAS thread per process)

import backend.layered.connect as connect  # noqa: E402
from backend.layered.walk import RR_EVAL, RR_SAMPLE, walk  # noqa: E402
from backend.materials.base import RADIANCE, ShadingContext  # noqa: E402

from .layered_throughput import STACKS, directions, load, timed  # noqa: E402

TARGET_EVAL_US = {"1 slab (Fig. 2 top)": 4.5, "2 slabs (reference, microflake)": 11.0}
TARGET_SAMPLE_US = {"1 slab (Fig. 2 top)": 1.0, "2 slabs (reference, microflake)": 2.3}


def count_connections(bsdf, wi, wo, rng):
    """Connections per lane of one bidirectional eval, keyed by the evaluated vertex
    ("interface l" or "medium k")."""
    counts: dict[str, int] = {}
    original = connect._block

    def counting(stack, s, l_if, is_medium, B, G, si, *a, **k):
        key = f"medium {s}" if is_medium else f"interface {l_if}"
        counts[key] = counts.get(key, 0) + int(si.size)
        return original(stack, s, l_if, is_medium, B, G, si, *a, **k)

    connect._block = counting
    try:
        bsdf.eval(wi, wo, rng, RADIANCE, estimator="bi")
    finally:
        connect._block = original
    n = wi.shape[0]
    return {k: v / n for k, v in sorted(counts.items())}


def count_vertices(stack, w, rng, rr):
    """Vertices per walk by kind ("interface l" / "medium k") of walks from directions w."""
    r = walk(stack, np.ascontiguousarray(w.T), rng, rr=rr)
    rec = r.records
    out = {}
    for kind, name in ((1, "interface"), (0, "medium")):
        for l in np.unique(rec.layer[rec.kind == kind]):
            out[f"{name} {int(l)}"] = float(np.count_nonzero((rec.kind == kind) & (rec.layer == l))) / w.shape[0]
    return out


def _pairs(rng, m, transmit_mix: bool):
    """(3, m) direction pairs away from a vertex: wi above, wo above (or half of them below)."""
    wi = directions(rng, m).T.copy()
    wo = directions(rng, m).T.copy()
    if transmit_mix:
        wo[2] *= np.where(rng.random(m) < 0.5, -1.0, 1.0)
    return wi, wo


def interface_costs(stack, rng, block, repeat):
    """µs per evaluation (value + both densities) and per sample of each non-delta interface."""
    out = {}
    for l, ker in enumerate(stack.kernels):
        if ker.delta_only:
            continue
        wi, wo = _pairs(rng, block, transmit_mix=getattr(ker, "eta", None) is not None)
        if ker.generic:
            t_eval, _ = timed(lambda: ker.eval(wi, wo, rng, True), repeat)
        else:
            ti, to = ker.mask_terms(wi), ker.mask_terms(wo)
            t_eval, _ = timed(lambda: ker.eval(wi, wo, rng, True, False, ti=ti, to=to), repeat)
        t_samp, _ = timed(lambda: ker.sample(wi, rng, True) if ker.generic else
                          ker.sample(wi, rng, True, False), repeat)
        out[l] = (t_eval / block * 1e6, t_samp / block * 1e6)
    return out


def medium_costs(stack, rng, block, repeat):
    """µs per phase connection (value + reverse density) and per phase sample of each medium."""
    out = {}
    for k, slab in enumerate(stack.slabs):
        if slab is None:
            continue
        ph = slab.phase.take(np.zeros(block, dtype=np.int64))
        a = directions(rng, block).T.copy()
        b = directions(rng, block).T.copy()
        b[2] *= np.where(rng.random(block) < 0.5, -1.0, 1.0)
        sa = sb = None
        if slab.directional:
            sa, sb = ph.sigma3(a), ph.sigma3(b)
        t_conn, _ = timed(lambda: ph.connect(a, b, sa, sb), repeat)
        t_samp, _ = timed(lambda: ph.sample3(-a, rng, sa), repeat)
        out[k] = (t_conn / block * 1e6, t_samp / block * 1e6)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", type=int, default=65536)
    ap.add_argument("--block", type=int, default=connect.BLOCK)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(7)
    print(f"machine: {platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}; "
          f"one process, CPU time, best of {args.repeat}")
    wi, wo = directions(rng, args.lanes), directions(rng, args.lanes)
    for name, d in STACKS.items():
        bsdf = load(d).bind(ShadingContext(np.zeros((args.lanes, 2))))
        stack = bsdf.stack
        t_eval, _ = timed(lambda: bsdf.eval(wi, wo, rng, RADIANCE, estimator="bi"), args.repeat)
        t_samp, _ = timed(lambda: bsdf.sample(wi, rng, RADIANCE, want_pdf=False), args.repeat)
        counts = count_connections(bsdf, wi, wo, rng)
        ifc = interface_costs(stack, rng, args.block, args.repeat)
        med = medium_costs(stack, rng, args.block, args.repeat)

        def cost_of(key, which):   # which: 0 = evaluation, 1 = sample
            kind, idx = key.split()
            return (ifc if kind == "interface" else med)[int(idx)][which]

        print(f"\n{name}")
        conn = 0.0
        for key, c in counts.items():
            cost = cost_of(key, 0)
            conn += c * cost
            print(f"  connections to {key:12s}: {c:5.1f} per eval x {cost * 1e3:4.0f} ns = {c * cost:5.2f} us")
        walks = {}
        for label, rr in (("eval", RR_EVAL), ("sample", RR_SAMPLE)):
            verts = count_vertices(stack, wi, rng, rr)
            walks[label] = sum(v * cost_of(k, 1) for k, v in verts.items()
                               if not (k.startswith("interface") and stack.kernels[int(k.split()[1])].delta_only))
            desc = ", ".join(f"{k} {v:.2f}" for k, v in verts.items())
            print(f"  vertices per {label} walk: {desc} -> vertex sampling {walks[label]:5.2f} us")
        floor_eval = conn + 2.0 * walks["eval"]      # the walk from wi and the walk from wo
        m_eval, m_samp = t_eval / args.lanes * 1e6, t_samp / args.lanes * 1e6
        print(f"  eval floor (connection vertex functions + two walks' vertex sampling): {floor_eval:5.2f} us; "
              f"measured {m_eval:5.2f} us ({floor_eval / m_eval:4.0%} of it)")
        print(f"  sample floor (the walk's vertex sampling): {walks['sample']:5.2f} us; measured {m_samp:5.2f} us "
              f"({walks['sample'] / m_samp:4.0%} of it)")
        if name in TARGET_EVAL_US:
            te, ts = TARGET_EVAL_US[name], TARGET_SAMPLE_US[name]
            print(f"  issue 3 goal: eval <= {te} us (floor = {floor_eval / te:4.0%} of it), "
                  f"sample <= {ts} us (floor = {walks['sample'] / ts:4.0%} of it)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
