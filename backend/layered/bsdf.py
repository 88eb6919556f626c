"""The layered BSDF bound to n shading points: sample / eval / pdf over arrays of lanes, for NumPy
callers (the BSDF inspector, tests). A thin wrapper: every query is one batch loop over lanes
(backend/kernels/layered/batch.py ``run``) calling the same compiled per-lane estimators as the
integrator (backend/kernels/layered/estimators.py, whose docstring describes them).

Three independent stochastic quantities (never combined as eval/pdf):
* ``sample``: a forward walk from wi; its throughput at the exit is the weight f·|cos|/p.
* ``eval``: the bidirectional (default) or unidirectional estimator of f·|cos θo|.
* ``pdf``: the approximate pdf (media removed, short interface paths, plus a constant) or the
  stochastic unbiased estimate of the sampler's density; only for MIS weights.

Random numbers: each call draws one seed from the caller's generator; lane i then uses the
counter-based stream ``path_key(seed, i, 0)`` (kernels/rng.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import stats as global_stats
from ..materials.base import BSDF, IMPORTANCE, RADIANCE, BSDFSample, taken
from .phase.base import draw_seed


@dataclass(frozen=True)
class Options:
    estimator: str = "auto"      # "auto" (a closed form where the stack has one, else "bi") | "bi" | "uni"
    pdf: str = "lobes"           # "lobes" | "approx" | "stochastic"
    pdf_constant: float = 0.1    # added to the lobes and approximate pdfs (sr⁻¹); Guo's diffusePdf
    max_vertices: int = 1024     # hard cap per walk; hits are counted in ``stats``
    mis: bool = True             # uni only: False = NEE alone where it applies (benchmarks)


ESTIMATORS = {"bi": 0, "uni": 1, "auto": 0}
PDF_KINDS = {"approx": 0, "stochastic": 1, "lobes": 4, "stochastic-bi": 2, "approx-bi": 3}   # the last two: benchmarks


def new_stats() -> dict:
    return {"walks": 0, "vertices": 0, "cap_hits": 0}


def _rows3(x, n=None):
    a = np.ascontiguousarray(np.asarray(x, dtype=np.float64).reshape(-1, 3))
    return a


class LayeredBSDF(BSDF):
    stochastic = True
    has_delta = True

    def __init__(self, material, uv: np.ndarray, n: int | None = None, stats: dict | None = None):
        self.material = material
        self.uv = np.ascontiguousarray(np.asarray(uv, dtype=np.float64).reshape(-1, 2))
        self.n = int(n if n is not None else self.uv.shape[0])
        self.options = material.options
        self.transmissive = material.transmissive
        self.stats = stats if stats is not None else material.stats

    # ------------------------------------------------------------------ plumbing
    def _run(self, op, wi, wo=None, nee=None, rng=None, mode=RADIANCE, est=-1, kind=-1,
             want_pdf=True, nee_pdf=True, want_sample=True):
        from ..kernels.layered import batch
        from ..kernels.workitems import WalkScratch
        ST, TX, s = self.material.kernel_table()
        wi = _rows3(wi)
        n = wi.shape[0]
        wo = wi if wo is None else _rows3(wo)
        nee = np.ones(1, bool) if nee is None else np.ascontiguousarray(np.asarray(nee, dtype=bool).reshape(-1))
        if nee.size == 1 and n > 1:
            nee = np.broadcast_to(nee, (n,)).copy()
        uv = self.uv if self.uv.shape[0] in (1, n) else np.broadcast_to(self.uv[:1], (n, 2)).copy()
        walk = WalkScratch(*batch.scratch(self.options.max_vertices))
        C = walk.counters
        out = batch.Answers(np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n),
                            np.zeros(n, bool))
        seed = draw_seed(rng if rng is not None else np.random.default_rng())
        query = batch.Query(op=op, mode=int(mode), est=int(est), kind=int(kind), want_pdf=bool(want_pdf),
                            nee_pdf=bool(nee_pdf), want_sample=bool(want_sample), seed=seed)
        batch.run(query, ST, TX, s, uv, wi, wo, nee, walk, out)
        f, p, wo_s, w_s, p_s, d_s = out
        self.stats["walks"] += int(C[0])
        self.stats["vertices"] += int(C[1])
        if C[2]:
            self.stats["cap_hits"] += int(C[2])
            global_stats.add("layered_walk_cap_hits", int(C[2]))
        return f, p, wo_s, w_s, p_s, d_s

    # ------------------------------------------------------------------ queries
    def eval(self, wi, wo, rng, mode=RADIANCE, estimator: str | None = None):
        from ..kernels.layered import batch
        est = ESTIMATORS[estimator] if estimator else -1
        return self._run(batch.OP_EVAL, wi, wo, rng=rng, mode=mode, est=est)[0]

    def pdf(self, wi, wo, rng, mode=RADIANCE, kind: str | None = None):
        from ..kernels.layered import batch
        k = PDF_KINDS[kind] if kind else -1
        return self._run(batch.OP_PDF, wi, wo, rng=rng, mode=mode, kind=k)[1]

    def sample(self, wi, rng, mode=RADIANCE, want_pdf: bool = True) -> BSDFSample:
        """Forward walk from wi. ``want_pdf=False`` skips the MIS pdf estimate (e.g. for albedo
        integration), leaving ``pdf`` 0."""
        from ..kernels.layered import batch
        _, _, wo, w, p, d = self._run(batch.OP_SAMPLE, wi, rng=rng, mode=mode, want_pdf=want_pdf)
        return BSDFSample(wo, w, p, d)

    def nee_and_sample(self, wi, wo, nee, rng, nee_pdf: bool = True, want_sample: bool = True):
        """The light connection and the continuation sample of one path vertex (RADIANCE), as the
        integrator computes them per lane: with the bidirectional estimator from one walk from wi
        (estimators.nee_and_sample); otherwise as separate queries (the base class)."""
        if not want_sample or self.options.estimator == "uni":
            return super().nee_and_sample(wi, wo, nee, rng, nee_pdf, want_sample)
        from ..kernels.layered import batch
        f, p, wo_s, w, ps, d = self._run(batch.OP_NEE, wi, wo, nee=nee, rng=rng, nee_pdf=nee_pdf,
                                         want_sample=want_sample)
        return f, p, BSDFSample(wo_s, w, ps, d)

    def albedo(self):
        """A one-sample estimate of the normal-incidence albedo per lane (for the denoising AOV:
        averaged over the pixel's samples it converges to the directional albedo)."""
        from ..kernels.layered import batch
        wi = np.zeros((self.n, 3))
        wi[:, 2] = 1.0
        return self._run(batch.OP_ALBEDO, wi, rng=np.random.default_rng(self.n), mode=IMPORTANCE)[3]

    def take(self, idx) -> "LayeredBSDF":
        idx = np.asarray(idx)
        n = taken(idx)
        uv = self.uv if self.uv.shape[0] == 1 else self.uv[idx]
        return LayeredBSDF(self.material, uv, n, self.stats)
