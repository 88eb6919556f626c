"""The layered BSDF bound to n shading points: sample / eval / pdf over arrays of lanes.

Three independent stochastic quantities (never combined as eval/pdf):
* ``sample``: a forward walk from wi; its throughput at the exit is the weight f·|cos|/p.
* ``eval``: the bidirectional (default) or unidirectional estimator of f·|cos θo|.
* ``pdf``: the approximate pdf (media removed, short interface paths, plus a constant) or the
  stochastic unbiased estimate of the sampler's density; only for MIS weights, computed with
  random numbers independent of the value's.

Transport modes: the walks use importance transport, which estimates the physical flow
wi → wo. RADIANCE (camera paths) wants the flow wo → wi, equal to it times (η_wi/η_wo)² by the
generalised reciprocity of the whole stack (η = index outside the stack on each side); reflections
are unchanged.

Sides: a reflection-only stack (opaque bottom) is two-sided — the integrator turns the frame to
the viewer — so queries with wi or wo below the surface return 0. A transmissive stack is
one-sided: wi below the surface enters through the bottom interface.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import stats as global_stats
from ..materials.base import BSDF, IMPORTANCE, RADIANCE, BSDFSample
from .connect import bidirectional
from .nee import unidirectional
from .stack import BoundStack
from .walk import RR_OFF, RR_SAMPLE, walk

CHUNK = 65536  # lanes per walk batch: large batches amortise per-call overhead (measured: 16384 lanes cost 30 % more per lane); bounds record memory (~100 MB)


@dataclass(frozen=True)
class Options:
    estimator: str = "bi"        # "bi" | "uni"
    pdf: str = "approx"          # "approx" | "stochastic"
    pdf_constant: float = 0.1    # added to the approximate pdf (sr⁻¹); Guo's diffusePdf
    max_vertices: int = 1024     # hard cap per walk; hits are counted in ``stats``
    mis: bool = True             # uni only: False = NEE alone where it applies (benchmarks)


def new_stats() -> dict:
    return {"walks": 0, "vertices": 0, "cap_hits": 0}


class LayeredBSDF(BSDF):
    stochastic = True
    has_delta = True

    def __init__(self, stack: BoundStack, options: Options, stats: dict | None = None):
        self.stack = stack
        self.n = stack.n
        self.options = options
        self.transmissive = stack.transmissive
        self.stats = stats if stats is not None else new_stats()
        k = stack.kernels
        self._uni_blind_top = len(k) > 1 and k[0].delta_only and k[1].delta_only
        self._uni_blind_bottom = len(k) > 1 and k[-1].delta_only and k[-2].delta_only

    # ------------------------------------------------------------------ helpers
    def _note(self, result) -> None:
        self.stats["walks"] += result.exit_dir.shape[1]
        self.stats["vertices"] += result.vertices
        if result.capped:
            self.stats["cap_hits"] += result.capped
            global_stats.add("layered_walk_cap_hits", result.capped)

    def _walk(self, stack, w, rng, **kw):
        r = walk(stack, w, rng, max_vertices=self.options.max_vertices, **kw)
        self._note(r)
        return r

    def _valid(self, wi, wo=None) -> np.ndarray:
        if self.transmissive:
            ok = wi[:, 2] != 0
            return ok if wo is None else ok & (wo[:, 2] != 0)
        ok = wi[:, 2] > 0
        return ok if wo is None else ok & (wo[:, 2] > 0)

    def _mode_factor(self, wi, wo, mode) -> np.ndarray:
        if mode != RADIANCE or not self.transmissive:
            return np.ones(wi.shape[0])
        s = self.stack
        ei = np.where(wi[:, 2] > 0, s.eta_top, s.eta_bottom)
        eo = np.where(wo[:, 2] > 0, s.eta_top, s.eta_bottom)
        return (ei / eo) ** 2

    def _chunks_of(self, lanes: np.ndarray):
        """(lane indices, stack for them) in batches of at most CHUNK lanes."""
        if lanes.size == 0:
            return
        if lanes.size == self.n and self.n <= CHUNK:
            yield lanes, self.stack
            return
        for start in range(0, lanes.size, CHUNK):
            idx = lanes[start:start + CHUNK]
            yield idx, self.stack.take(idx)

    @staticmethod
    def _single(stack: BoundStack, a, b, rng, pdf: bool):
        """The one-vertex path: reflection at the entry interface (exact). a, b: (3, m)."""
        m = a.shape[1]
        out = np.zeros(m) if pdf else np.zeros((3, m))
        same = a[2] * b[2] > 0
        for l, side in ((0, a[2] > 0), (stack.N - 1, a[2] < 0)):
            pos = np.flatnonzero(same & side)
            if not pos.size or stack.kernels[l].delta_only:
                continue
            ker = stack.kernels[l].take(pos)
            v, pf, _ = ker.eval(a[:, pos], b[:, pos], rng, need_rev=False)
            if pdf:
                out[pos] = pf
            else:
                # Normal map: the arrival factor of the segment from the outside (the exit one is
                # the kernel's shading cosine times eval's 1/|cos θo|·|cos θo|).
                out[:, pos] = v * ker.arrival(a[:, pos]) if ker.framed else v
        return out

    # ------------------------------------------------------------------ estimators
    # One chunk's lanes as (3, m) arrays. The walks from wi and from wo of a query run as one
    # joint walk over 2m lanes (stack.expand): a lock-step walk's cost per iteration is largely
    # per NumPy call, not per lane, so one walk of 2m lanes costs much less than two of m.

    def _joint_walk(self, stack: BoundStack, a, b, rng, **kw):
        m = a.shape[1]
        both = stack.expand(np.concatenate([np.arange(m), np.arange(m)]))
        return walk(both, np.concatenate([a, b], axis=1), rng, **kw)

    def _value(self, stack: BoundStack, a, b, rng, est: str):
        """(3, m) f·|cos θo| (importance transport)."""
        f = self._single(stack, a, b, rng, pdf=False)
        if stack.N == 1:
            return f
        if est == "uni":
            f += unidirectional(stack, b, self._walk(stack, a, rng).records, rng, mis=self.options.mis)
            # NEE through the exit interface needs a non-delta interface at the exit or across
            # the slab next to it; otherwise the paths "medium → specular → specular exit" have
            # no unidirectional strategy: use the bidirectional estimator there.
            need_bi = np.flatnonzero(np.where(b[2] > 0, self._uni_blind_top, self._uni_blind_bottom))
            if need_bi.size:
                f[:, need_bi] = self._value(stack.take(need_bi), a[:, need_bi], b[:, need_bi], rng, "bi")
            return f
        J = self._joint_walk(stack, a, b, rng, max_vertices=self.options.max_vertices)
        self._note(J)
        f += bidirectional(stack, b, J.records, J.records, rng, R_off=a.shape[1]) * np.abs(b[2])
        return f

    def _pdf(self, stack: BoundStack, a, b, rng, kind: str):
        """(m,) the approximate or stochastic pdf estimate."""
        approx = kind != "stochastic"
        p = self._single(stack, a, b, rng, pdf=True)
        if stack.N > 1:
            nmax = None
            cap = self.options.max_vertices
            if approx:
                slabs = stack.N - 1
                nmax = np.where(a[2] * b[2] > 0, 2 * slabs + 1, slabs + 1)
                cap = 2 * slabs
            # No roulette in the stochastic pdf's walks: the sampler's density does not decay
            # along a path (absorption only lowers sample weights), so roulette compensation
            # compounds and makes the estimate heavy-tailed (measured, Fig. 2 stack: variance
            # ÷11 at 3.3× the time without it). The vertex cap still bounds the walks.
            hero = None
            if not approx and any(sl is not None and not sl.grey for sl in stack.slabs):
                # Chromatic extinction: the walks from both ends share a hero channel (walk.walk).
                hero = np.minimum((rng.random(a.shape[1]) * 3.0).astype(np.int64), 2)
            J = self._joint_walk(stack, a, b, rng, approx=approx, max_vertices=cap, purpose="pdf",
                                 rr=RR_OFF, hero=None if hero is None else np.concatenate([hero, hero]))
            if not approx:
                self._note(J)
            p += bidirectional(stack, b, J.records, J.records, rng, pdf_mode=True, approx=approx,
                               nmax=nmax, R_off=a.shape[1], hero=None if J.hero is None else hero)
        if approx:
            p += self.options.pdf_constant
        return p

    # ------------------------------------------------------------------ queries
    def eval(self, wi, wo, rng, mode=RADIANCE, estimator: str | None = None):
        n = wi.shape[0]
        out = np.zeros((n, 3))
        est = estimator or self.options.estimator
        valid = np.flatnonzero(self._valid(wi, wo))
        for idx, stack in self._chunks_of(valid):
            a, b = np.ascontiguousarray(wi[idx].T), np.ascontiguousarray(wo[idx].T)
            out[idx] = self._value(stack, a, b, rng, est).T
        return out * self._mode_factor(wi, wo, mode)[:, None]

    def pdf(self, wi, wo, rng, mode=RADIANCE, kind: str | None = None):
        n = wi.shape[0]
        out = np.zeros(n)
        kind = kind or self.options.pdf
        valid = np.flatnonzero(self._valid(wi, wo))
        for idx, stack in self._chunks_of(valid):
            a, b = np.ascontiguousarray(wi[idx].T), np.ascontiguousarray(wo[idx].T)
            out[idx] = self._pdf(stack, a, b, rng, kind)
        return out

    def sample(self, wi, rng, mode=RADIANCE, want_pdf: bool = True) -> BSDFSample:
        """Forward walk from wi. ``want_pdf=False`` skips the MIS pdf estimate (e.g. for albedo
        integration), leaving ``pdf`` 0."""
        n = wi.shape[0]
        wo = np.zeros((n, 3))
        weight = np.zeros((n, 3))
        delta = np.zeros(n, dtype=bool)
        valid = np.flatnonzero(self._valid(wi))
        for idx, stack in self._chunks_of(valid):
            r = self._walk(stack, np.ascontiguousarray(wi[idx].T), rng, record=False, rr=RR_SAMPLE)
            wo[idx] = r.exit_dir.T
            weight[idx] = r.exit_weight.T
            delta[idx] = r.exit_delta
        exited = np.any(weight > 0, axis=1)
        weight *= self._mode_factor(wi, wo, mode)[:, None]
        pdf = np.zeros(n)
        need = np.flatnonzero(exited & ~delta) if want_pdf else np.zeros(0, dtype=np.int64)
        if need.size:
            sub = self if need.size == n else self.take(need)
            pdf[need] = sub.pdf(wi[need], wo[need], rng, mode)
        return BSDFSample(wo, weight, pdf, delta & exited)

    def nee_and_sample(self, wi, wo, nee, rng, nee_pdf: bool = True, want_sample: bool = True):
        """The light connection and the continuation sample of one path vertex from one joint
        walk: the walk from wi that the bidirectional eval connects is a forward walk from wi,
        so its exit is also a sample of the BSDF (walk.walk records it either way). This saves
        the separate sample walk and its per-call overhead (measured on the render benchmark of
        benchmarks/layered_throughput.py, 128², 16 spp: render time −5 % (one slab), −21 % (two
        microflake slabs), −14 % (three slabs), image variance unchanged within its ±5 %).

        Both results stay unbiased: the eval estimate is unchanged, and the exit of a forward
        walk is the sampler whatever else the walk is used for; they are correlated, which only
        affects variance. The continuation walk uses eval's roulette (walk.RR_EVAL): its weight
        alone is noisier than sample()'s (RR_SAMPLE; variance 1.1–2.2× per direction cell), but
        the image noise per unit time is lower. Giving the wi half of the walk RR_SAMPLE instead
        (tried) keeps the weight's variance but lengthens the walks the connections run over:
        render time back to that of separate queries.
        The sampled direction's MIS pdf and the light direction's pdf run as one pdf query."""
        if not want_sample or self.options.estimator != "bi" or self.stack.N == 1:
            return super().nee_and_sample(wi, wo, nee, rng, nee_pdf, want_sample)
        n = wi.shape[0]
        f = np.zeros((n, 3))
        wo_s = np.zeros((n, 3))
        weight = np.zeros((n, 3))
        delta = np.zeros(n, dtype=bool)
        can_sample = self._valid(wi)
        conn = np.asarray(nee, dtype=bool) & self._valid(wi, wo)
        conn_lanes = np.flatnonzero(conn)
        # Lanes with a light connection first: each batch then connects a prefix of its walks.
        order = np.concatenate([conn_lanes, np.flatnonzero(can_sample & ~conn)])
        identity = order.size == n and bool(np.all(order == np.arange(n)))
        for start in range(0, order.size, CHUNK):
            idx = order[start:start + CHUNK]
            m = idx.size
            me = int(min(max(conn_lanes.size - start, 0), m))
            stack = self.stack if identity and n <= CHUNK else self.stack.take(idx)
            a = np.ascontiguousarray(wi[idx].T)
            b = np.ascontiguousarray(wo[idx[:me]].T)
            both = stack.expand(np.concatenate([np.arange(m), np.arange(me)]))
            J = walk(both, np.concatenate([a, b], axis=1), rng, max_vertices=self.options.max_vertices)
            self._note(J)
            wo_s[idx] = J.exit_dir[:, :m].T
            weight[idx] = J.exit_weight[:, :m].T
            delta[idx] = J.exit_delta[:m]
            if me:
                se = stack if me == m else stack.expand(np.arange(me))
                fe = self._single(se, a[:, :me], b, rng, pdf=False)
                fe += bidirectional(se, b, J.records, J.records, rng, R_off=m) * np.abs(b[2])
                f[idx[:me]] = fe.T
        f *= self._mode_factor(wi, wo, RADIANCE)[:, None]
        exited = np.any(weight > 0, axis=1)
        weight *= self._mode_factor(wi, wo_s, RADIANCE)[:, None]
        # Both MIS pdfs (light direction, sampled direction) in one query.
        need = np.flatnonzero(exited & ~delta)
        rows = np.concatenate([conn_lanes, need]) if nee_pdf else need
        p_all = np.zeros(rows.size)
        if rows.size:
            sub = self if rows.size == n and bool(np.all(rows == np.arange(n))) else self.take(rows)
            dirs = np.concatenate([wo[conn_lanes], wo_s[need]]) if nee_pdf else wo_s[need]
            p_all = sub.pdf(wi[rows], dirs, rng, RADIANCE)
        pdf_nee = np.zeros(n)
        pdf_s = np.zeros(n)
        k = conn_lanes.size if nee_pdf else 0
        if nee_pdf:
            pdf_nee[conn_lanes] = p_all[:k]
        pdf_s[need] = p_all[k:]
        return f, pdf_nee, BSDFSample(wo_s, weight, pdf_s, delta & exited)

    def albedo(self):
        """A one-sample estimate of the normal-incidence albedo per lane (for the denoising AOV:
        averaged over the pixel's samples it converges to the directional albedo)."""
        rng = np.random.default_rng(self.n)
        wi = np.zeros((self.n, 3))
        wi[:, 2] = 1.0
        s = self.sample(wi, rng, IMPORTANCE, want_pdf=False)
        return np.where((s.wo[:, 2] > 0)[:, None], s.weight, 0.0)

    def take(self, idx) -> "LayeredBSDF":
        return LayeredBSDF(self.stack.take(idx), self.options, self.stats)
