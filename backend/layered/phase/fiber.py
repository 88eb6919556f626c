"""The microflake "fiber" phase function of Guo et al. 2018 (after Jakob et al. 2010; Heitz et al. 2015).

Flake distribution. Specular flakes whose normals m cluster around the plane perpendicular to the
fiber axis t, with a Gaussian density in x = m·t:

    D(m) = exp(−x² / (2 s²)) / (2π N(s)),   N(s) = ∫_{−1}^{1} exp(−x²/(2s²)) dx = s √(2π) erf(1/(s√2)),

normalised so that ∫_{S²} D dm = 1 (dm = dx dφ on the sphere). ``s`` is the "stddev" parameter.

Projected area. σ_fiber(ω) = ∫_{S²} |ω·m| D(m) dm (both flake sides count). It depends on s and on
the angle θ between ω and t only. Limits (tests check them):
    s → 0:  σ → (2/π) sin θ (flakes in a plane: the average of |sin θ cos φ|);
    s → ∞:  σ → 1/2 (uniform flake normals);
    θ = 0:  σ = E|x| = 2 s² (1 − e^{−1/(2s²)}) / N(s) exactly.
Extinction is σt(ω) = density · 2 σ_fiber(ω), so ``sigma_scale`` = 2 σ_fiber (→ 1 for isotropic flakes).

Phase. With ωi = −d_in and ωo = d_out (the two directions pointing away from the flake) and
h = (ωi + ωo)/|ωi + ωo|, a specular flake scatters with

    p(d_in → d_out) = D(h) / (2 σ_fiber(d_in)),

normalised over d_out: reflection maps h ↦ ωo with dωo = 4 |ωi·h| dh, and ±h give the same ωo.
Like every microflake phase with direction-dependent σ it is *not* reciprocal by itself;
σ_fiber(a) p(a → b) = σ_fiber(b) p(−b → −a) is (that is σs·p, the quantity the RTE needs).

σ_fiber is computed here, not copied: for a given (s, θ) the φ integral of |A + B cos φ| has the
closed form (2/π)(A asin(A/B) + √(B² − A²)) for |A| < B (and |A| otherwise), leaving one integral
over the flake elevation, done with Gauss–Legendre panels split at the kink (α = θ) and at multiples
of s. The values are tabulated over (ln s, q) with q = asinh(θ/s)/asinh(π/(2s))
(which resolves the width-s transition near θ = 0 for small s) and read back with 4×4-point
Lagrange interpolation (relative error ≲ 3e-6 against the quadrature, see tests/test_phase.py).
The table ships as fiber_sigma_table.npz (tools/gen_fiber_table.py); it is computed only if that
file is missing or was made for another grid.

Sampling (exact, no tables). The reflected direction is exact when h is drawn from the visible-
normal density D(m)|ωi·m|/σ_fiber(ωi). Write m = x t + √(1 − x²)(cos φ e1 + sin φ e2) and
c = ωi·t, sθ = |ωi × t|; then |ωi·m| ≤ |c||x| + sθ =: M(x). Draw x with density ∝ e^{−x²/2s²} M(x)
(a mixture of a Rayleigh-like and a normal variable, truncated to |x| ≤ 1 by rejection) and φ
uniform, and accept with probability |ωi·m|/M(x). For s > 0.7 x is drawn uniformly instead and
accepted with probability e^{−x²/2s²}|ωi·m|/(|c| + sθ). Acceptance is ≳ 0.2 per round in the worst
case; lanes still rejected after ``MAX_ROUNDS`` rounds return weight 0 and are counted in
``stats.failures`` (a statistic, expected ~0).
"""
from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np

from ...mathutil import coordinate_system, cross, dot
from .base import (Phase, PhaseSample, lane_count, lanes, scalar_lanes, unit_or,
                   vector_lanes)

S_MIN, S_MAX = 1e-3, 4.0   # stddev range (clamped); Mitsuba's fiber table spans 4e-8 … 4
MAX_ROUNDS = 128           # rejection cap per sample
UNIFORM_ABOVE = 0.7        # stddev above which x is proposed uniformly (better acceptance)
EXTRA = 4                  # candidates per lane in the rounds after the first (acceptance ≳ 0.2)

# Table layout: rows uniform in ln s, columns uniform in q; one ghost row/column on each side
# so the 4-point stencil never leaves the table (σ is even in θ and in θ − π/2, so ghost
# columns are just evaluated at |θ| or π − θ).
_LN_S0, _LN_S1 = math.log(S_MIN), math.log(S_MAX)
_ROWS = 161
_COLS = 161
_H_S = (_LN_S1 - _LN_S0) / (_ROWS - 1)
_H_Q = 1.0 / (_COLS - 1)


# ------------------------------------------------------------------------------ quadrature
def gauss_norm(s: float) -> float:
    """N(s) = ∫_{−1}^{1} exp(−x²/(2s²)) dx (scalar)."""
    return s * math.sqrt(2.0 * math.pi) * math.erf(1.0 / (s * math.sqrt(2.0)))


def _phi_average(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(1/2π) ∫_0^{2π} |a + b cos φ| dφ for a ≥ 0, b ≥ 0."""
    inside = a < b
    bb = np.where(inside, b, 1.0)
    r = np.clip(a / bb, -1.0, 1.0)
    closed = (2.0 / np.pi) * (a * np.arcsin(r) + np.sqrt(np.maximum(b * b - a * a, 0.0)))
    return np.where(inside, closed, a)


@lru_cache(maxsize=None)
def _gl(n: int):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def projected_area_quadrature(s: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray,
                              nodes: int = 24) -> np.ndarray:
    """σ_fiber(s, θ) by quadrature (no table); arrays of equal shape (m,). Slow-ish: for tables/tests.

    σ = 2/N(s) ∫_0^{π/2} e^{−sin²α/(2s²)} Φ(|cos θ| sin α, sin θ cos α) cos α dα with x = sin α
    (the substitution removes the √(1 − x²) end-point singularity), Φ = ``_phi_average``.
    """
    s = np.asarray(s, dtype=np.float64).ravel()
    c = np.abs(np.asarray(cos_t, dtype=np.float64)).ravel()
    sn = np.abs(np.asarray(sin_t, dtype=np.float64)).ravel()
    theta = np.arctan2(sn, c)
    half_pi = 0.5 * np.pi
    cuts = [np.zeros_like(s), np.full_like(s, half_pi), theta]
    for k in (0.5, 1.0, 2.0, 4.0, 8.0):
        cuts.append(np.arcsin(np.minimum(1.0, k * s)))
    cuts = np.sort(np.stack(cuts, axis=1), axis=1)            # (m, P+1)
    lo, hi = cuts[:, :-1], cuts[:, 1:]                        # (m, P)
    y, w = _gl(nodes)
    # Smoothstep map inside each panel: clusters nodes at both ends, where Φ has its
    # (x − x_kink)^{3/2} behaviour, so Gauss–Legendre keeps converging fast.
    ss = y * y * (3.0 - 2.0 * y)
    dss = 6.0 * y * (1.0 - y)
    alpha = lo[..., None] + (hi - lo)[..., None] * ss          # (m, P, nodes)
    jac = (hi - lo)[..., None] * dss * w
    sa, ca = np.sin(alpha), np.cos(alpha)
    ssq = (s * s)[:, None, None]
    f = np.exp(-sa * sa / (2.0 * ssq)) * _phi_average(c[:, None, None] * sa, sn[:, None, None] * ca) * ca
    integral = (f * jac).sum(axis=(1, 2))
    norm = np.array([gauss_norm(v) for v in s])
    return 2.0 * integral / norm


# ------------------------------------------------------------------------------ the table
def _q_of(theta: np.ndarray, s: np.ndarray) -> np.ndarray:
    return np.arcsinh(theta / s) / np.arcsinh(0.5 * np.pi / s)


TABLE_NODES = 16          # Gauss–Legendre nodes per panel for the table entries
TABLE_FILE = Path(__file__).with_name("fiber_sigma_table.npz")


def table_grid() -> np.ndarray:
    """What the table's values depend on (checked when the shipped file is read)."""
    return np.array([S_MIN, S_MAX, _ROWS, _COLS, TABLE_NODES], dtype=np.float64)


def compute_table():
    """(σ table (ROWS+2, COLS+2), ln N table (ROWS+2,)) by quadrature (~0.5 s)."""
    ln_s = _LN_S0 + _H_S * np.arange(-1, _ROWS + 1)
    q = _H_Q * np.arange(-1, _COLS + 1)
    s = np.exp(ln_s)
    theta = s[:, None] * np.sinh(q[None, :] * np.arcsinh(0.5 * np.pi / s)[:, None])
    ss = np.broadcast_to(s[:, None], theta.shape).ravel()
    th = theta.ravel()
    sigma = np.empty(th.shape)
    step = 4096
    for i in range(0, th.size, step):  # chunks bound the (m, panels, nodes) temporaries
        sl = slice(i, i + step)
        sigma[sl] = projected_area_quadrature(ss[sl], np.cos(th[sl]), np.sin(th[sl]), nodes=TABLE_NODES)
    ln_norm = np.log([gauss_norm(v) for v in s])
    return sigma.reshape(theta.shape), np.asarray(ln_norm)


def write_table(path: Path = TABLE_FILE) -> None:
    """Store ``compute_table()`` with its grid (tools/gen_fiber_table.py; tests check it is current)."""
    sigma, ln_norm = compute_table()
    np.savez(path, grid=table_grid(), sigma=sigma, ln_norm=ln_norm)


@lru_cache(maxsize=1)
def _table():
    """The σ and ln N tables: read from the file shipped next to this module, or computed where
    the file is missing or was made for another grid. Reading takes ~1 ms; the quadrature ~0.5 s,
    which every render process with a microflake medium would otherwise pay (17 % of a 64² preview
    of the reference stack, measured)."""
    try:
        with np.load(TABLE_FILE) as f:
            if np.array_equal(f["grid"], table_grid()):
                return np.array(f["sigma"]), np.array(f["ln_norm"])
    except (OSError, KeyError, ValueError):
        pass
    return compute_table()


def _lagrange4(t: np.ndarray) -> tuple:
    """Weights of the 4-point Lagrange interpolant at nodes −1, 0, 1, 2 for t ∈ [0, 1]."""
    tm1, tm2, tp1 = t - 1.0, t - 2.0, t + 1.0
    return (-t * tm1 * tm2 / 6.0, tp1 * tm1 * tm2 / 2.0, -tp1 * t * tm2 / 2.0, tp1 * t * tm1 / 6.0)


def _cell(x: np.ndarray, n_nodes: int):
    """Cell index i (stencil i−1..i+2 in ghosted indexing: i..i+3) and fraction, x in node units."""
    i = np.clip(np.floor(x), 0, n_nodes - 2).astype(np.int64)
    return i, x - i


def clamp_stddev(s) -> np.ndarray:
    return np.clip(np.asarray(s, dtype=np.float64), S_MIN, S_MAX)


def fiber_sigma(s, cos_t, sin_t=None, row=None) -> np.ndarray:
    """σ_fiber(s, θ) from the table. ``s`` () or (n,); cos_t (n,) = ω·t; sin_t = |ω × t| (optional,
    more accurate near θ = 0 than √(1 − cos²)). ``row``: ``table_row(s)`` for a constant s
    (saves the interpolation across stddev rows)."""
    s = clamp_stddev(s)
    c = np.abs(np.asarray(cos_t, dtype=np.float64))
    sn = np.sqrt(np.maximum(0.0, (1.0 - c) * (1.0 + c))) if sin_t is None else np.abs(sin_t)
    theta = np.arctan2(sn, c)
    j, fj = _cell(_q_of(theta, s) * (_COLS - 1), _COLS)
    wj = _lagrange4(fj)
    if s.ndim == 0:
        row = table_row(s) if row is None else row
        return wj[0] * row[j] + wj[1] * row[j + 1] + wj[2] * row[j + 2] + wj[3] * row[j + 3]
    sigma_t, _ = _table()
    s_b = np.broadcast_to(s, theta.shape)
    i, fi = _cell((np.log(s_b) - _LN_S0) / _H_S, _ROWS)
    wi = _lagrange4(fi)
    out = np.zeros(theta.shape)
    for a in range(4):
        acc = wj[0] * sigma_t[i + a, j]
        for b in range(1, 4):
            acc = acc + wj[b] * sigma_t[i + a, j + b]
        out = out + wi[a] * acc
    return out


def table_row(s) -> np.ndarray:
    """σ over the q columns (with ghosts) for one constant stddev, interpolated across rows."""
    s = clamp_stddev(s)
    sigma_t, _ = _table()
    i, f = _cell((np.log(s) - _LN_S0) / _H_S, _ROWS)
    w = _lagrange4(f)
    return sum(w[a] * sigma_t[int(i) + a] for a in range(4))


def ln_gauss_norm(s) -> np.ndarray:
    """ln N(s) from the table (4-point Lagrange in ln s); s () or (n,)."""
    s = clamp_stddev(s)
    _, ln_norm = _table()
    i, f = _cell((np.log(s) - _LN_S0) / _H_S, _ROWS)
    w = _lagrange4(f)
    return sum(w[a] * ln_norm[i + a] for a in range(4))


# ------------------------------------------------------------------------------ phase
def sin_between(d: np.ndarray, t: np.ndarray) -> np.ndarray:
    """|d × t| for unit rows (accurate near parallel, unlike √(1 − (d·t)²))."""
    x = cross(d, np.broadcast_to(t, d.shape))
    return np.sqrt(dot(x, x))


class MicroflakeFiber(Phase):
    """Guo et al.'s fiber microflake phase. ``stddev`` () or (n,); ``orientation`` (3,), (1, 3) or
    (n, 3) fiber axes in the layer frame (normalised here; a zero axis falls back to +x)."""

    type_name = "microflake"
    directional = True

    def __init__(self, stddev, orientation):
        super().__init__()
        self.stddev = clamp_stddev(scalar_lanes(stddev))
        self.axis = unit_or(vector_lanes(orientation), [1.0, 0.0, 0.0])
        self._ln_norm = ln_gauss_norm(self.stddev)
        self._row = table_row(self.stddev) if self.stddev.ndim == 0 else None
        self._scalars()
        self._fr = None

    def _scalars(self):
        """Per-phase constants of a constant stddev (None otherwise) for the hot paths."""
        s = self.stddev
        if s.ndim == 0:
            sv = float(s)
            self._inv_s = 1.0 / sv
            self._q_scale = (_COLS - 1) / math.asinh(0.5 * math.pi / sv)   # q in column units
            self._s_scalar = sv
        else:
            self._inv_s = self._q_scale = self._s_scalar = None

    @property
    def n(self):
        return lane_count(self.stddev, self.axis)

    def _sigma(self, d: np.ndarray) -> np.ndarray:
        return fiber_sigma(self.stddev, dot(d, self.axis), sin_between(d, self.axis), self._row)

    def sigma_scale(self, d):
        return 2.0 * self._sigma(d)

    def distribution(self, m: np.ndarray) -> np.ndarray:
        """D(m), normalised to 1 over the sphere."""
        x = dot(m, self.axis)
        s = self.stddev
        return np.exp(-x * x / (2.0 * s * s) - self._ln_norm) / (2.0 * np.pi)

    def eval(self, d_in, d_out):
        h = d_out - d_in  # ωi + ωo with ωi = −d_in
        length = np.sqrt(dot(h, h))
        ok = length > 1e-12  # exact forward scattering: h undefined, a set of measure zero
        h = h / np.where(ok, length, 1.0)[:, None]
        sigma = self._sigma(d_in)
        value = self.distribution(h) / (2.0 * np.maximum(sigma, 1e-300))
        return np.where(ok, value, 0.0)

    def connect(self, a, b, s_a=None, s_b=None):
        # h = normalise(d_out − d_in) = normalise(a + b); p(−a → b) = D(h)/(2σ(a)) = D(h)/s(a).
        s_a = self.sigma_scale(np.ascontiguousarray(a.T)) if s_a is None else s_a
        s_b = self.sigma_scale(np.ascontiguousarray(b.T)) if s_b is None else s_b
        hx, hy, hz = a[0] + b[0], a[1] + b[1], a[2] + b[2]
        l2 = hx * hx + hy * hy + hz * hz
        ok = l2 > 1e-24  # exact forward scattering: h undefined, a set of measure zero
        ax = self.axis.T  # (3, 1|m)
        x = hx * ax[0] + hy * ax[1] + hz * ax[2]
        s = self.stddev
        d = np.exp(-(x * x) / (np.where(ok, l2, 1.0) * (2.0 * s * s)) - self._ln_norm) * (0.5 / np.pi)
        d = np.where(ok, d, 0.0)
        return d / np.maximum(s_a, 1e-300), d / np.maximum(s_b, 1e-300)

    def sigma3(self, d):
        """sigma_scale for (3, m) directions."""
        ax = self.axis.T
        c = d[0] * ax[0] + d[1] * ax[1] + d[2] * ax[2]
        x = d[1] * ax[2] - d[2] * ax[1]
        y = d[2] * ax[0] - d[0] * ax[2]
        z = d[0] * ax[1] - d[1] * ax[0]
        sn = np.sqrt(x * x + y * y + z * z)
        if self._row is None:
            return 2.0 * fiber_sigma(self.stddev, c, sn, None)
        # Constant stddev (already clamped): fiber_sigma's table read with the row and the
        # q-scale precomputed (this runs once or twice per walk iteration and medium).
        row, q_scale = self._row, self._q_scale
        theta = np.arctan2(sn, np.abs(c))
        q = np.arcsinh(theta * self._inv_s) * q_scale
        j = np.minimum(q.astype(np.int64), _COLS - 2)   # q ≥ 0: truncation is the floor
        wj = _lagrange4(q - j)
        return 2.0 * (wj[0] * row[j] + wj[1] * row[j + 1] + wj[2] * row[j + 2] + wj[3] * row[j + 3])

    def _frame(self):
        """Unit fiber axes t and two unit vectors e1, e2 completing a frame, each (3, 1|n)."""
        if self._fr is None:
            t = self.axis.T
            e1, e2 = coordinate_system(np.ascontiguousarray(self.axis))
            self._fr = (t, np.ascontiguousarray(e1.T), np.ascontiguousarray(e2.T))
        return self._fr

    def sample(self, d_in, rng):
        d_out, weight, pdf, _, _ = self.sample3(np.ascontiguousarray(d_in.T), rng)
        return PhaseSample(np.ascontiguousarray(d_out.T), weight, pdf)

    def sample3(self, d_in, rng, s_in=None):
        """Rejection sampling of the visible flake normal (module docstring), on (3, m). Round 1
        proposes one candidate per lane; later rounds, on the few rejected lanes, propose
        ``EXTRA`` candidates each and keep the first accepted (fewer rounds of overhead). The
        density is D(m)/s(d_in) from the accepted normal (h = ±m for a mirror reflection)."""
        m = d_in.shape[1]
        wi = -d_in
        t, e1, e2 = self._frame()
        sv = self._s_scalar
        # A constant stddev keeps s and the proposal kind scalars (no per-lane gathers/selects).
        s_all = sv if sv is not None else np.broadcast_to(self.stddev, (m,))
        # ωi in the fiber frame: c = ωi·t, (p1, p2) = (ωi·e1, ωi·e2), sθ = |ωi × t| = |(p1, p2)|.
        c_all = wi[0] * t[0] + wi[1] * t[1] + wi[2] * t[2]
        p1_all = wi[0] * e1[0] + wi[1] * e1[1] + wi[2] * e1[2]
        p2_all = wi[0] * e2[0] + wi[1] * e2[1] + wi[2] * e2[2]
        sn_all = np.sqrt(p1_all * p1_all + p2_all * p2_all)
        x_acc = cphi_acc = sphi_acc = np.zeros(m)
        done = np.zeros(m, dtype=bool)
        todo = None if m else np.zeros(0, dtype=np.int64)   # None: every lane (round 1)
        rounds = 0
        while (todo is None or todo.size) and rounds < MAX_ROUNDS:
            reps = 1 if rounds == 0 else EXTRA
            rounds += 1
            if todo is None:
                sk, ck, snk, p1k, p2k = s_all, c_all, sn_all, p1_all, p2_all
                k = m
            else:
                lanes_k = np.tile(todo, reps)
                k = lanes_k.size
                sk = s_all if sv is not None else s_all[lanes_k]
                ck, snk = c_all[lanes_k], sn_all[lanes_k]
                p1k, p2k = p1_all[lanes_k], p2_all[lanes_k]
            ack = np.abs(ck)
            u = rng.random((5, k))
            uniform = (sv > UNIFORM_ABOVE) if sv is not None else sk > UNIFORM_ABOVE
            # Gaussian branch: x ∝ e^{−x²/2s²}(|c||x| + sθ) = a mixture with weights |c|·2s²
            # (Rayleigh part, |x| e^{−x²/2s²}) and sθ·s√(2π) (normal part); both drawn as
            # s·√(−2 ln(1 − u)) times a random sign or cos 2πu' (Box–Muller).
            if sv is not None and uniform:
                x = 2.0 * u[1] - 1.0
            else:
                wa = ack * (2.0 * sk * sk)
                wb = snk * (sk * math.sqrt(2.0 * math.pi))
                pick_a = u[0] * (wa + wb) < wa
                rho = sk * np.sqrt(-2.0 * np.log1p(-u[1]))
                x = rho * np.where(pick_a, np.where(u[4] < 0.5, 1.0, -1.0), np.cos(2.0 * np.pi * u[4]))
                if sv is None:
                    x = np.where(uniform, 2.0 * u[1] - 1.0, x)
            inside = np.abs(x) <= 1.0
            x = np.clip(x, -1.0, 1.0)
            r = np.sqrt(np.maximum(0.0, (1.0 - x) * (1.0 + x)))
            phi = 2.0 * np.pi * u[2]
            cph, sph = np.cos(phi), np.sin(phi)
            vis = np.abs(x * ck + r * (cph * p1k + sph * p2k))
            lim = u[3]
            if sv is None:
                bound = np.where(uniform, ack + snk, ack * np.abs(x) + snk)  # ≥ |ωi·m|
                lim = lim * bound * np.exp(np.where(uniform, x * x / (2.0 * sk * sk), 0.0))
            elif uniform:
                lim = lim * (ack + snk) * np.exp(x * x / (2.0 * sv * sv))
            else:
                lim = lim * (ack * np.abs(x) + snk)
            ok = inside & (vis > lim)
            if todo is None:
                # Round 1 proposes for every lane in order: its arrays are the accumulators.
                x_acc, cphi_acc, sphi_acc, done = x, cph, sph, ok
                todo = np.flatnonzero(~ok)
            else:
                okr = ok.reshape(reps, -1)
                first = np.argmax(okr, axis=0)
                any_ok = okr[first, np.arange(todo.size)]
                pick = first * todo.size + np.arange(todo.size)
                sel = pick[any_ok]
                idx = todo[any_ok]
                todo = todo[~any_ok]
                x_acc[idx], cphi_acc[idx], sphi_acc[idx] = x[sel], cph[sel], sph[sel]
                done[idx] = True
        self.stats.samples += m
        self.stats.failures += int(todo.size)
        self.stats.iterations += rounds
        r = np.sqrt(np.maximum(0.0, (1.0 - x_acc) * (1.0 + x_acc)))
        mx = x_acc * t[0] + r * (cphi_acc * e1[0] + sphi_acc * e2[0])
        my = x_acc * t[1] + r * (cphi_acc * e1[1] + sphi_acc * e2[1])
        mz = x_acc * t[2] + r * (cphi_acc * e1[2] + sphi_acc * e2[2])
        wm2 = 2.0 * (wi[0] * mx + wi[1] * my + wi[2] * mz)
        d_out = np.stack([wm2 * mx - wi[0], wm2 * my - wi[1], wm2 * mz - wi[2]])
        all_done = not todo.size
        if not all_done:
            d_out = np.where(done, d_out, d_in)
        s = self.stddev
        D = np.exp(-x_acc * x_acc / (2.0 * s * s) - self._ln_norm) * (0.5 / np.pi)
        s_in = self.sigma3(d_in) if s_in is None else s_in
        s_out = self.sigma3(d_out)
        pdf = D / np.maximum(s_in, 1e-300)
        rev = D / np.maximum(s_out, 1e-300)
        if all_done:
            return d_out, np.ones(m), pdf, rev, s_out
        return d_out, done * 1.0, np.where(done, pdf, 0.0), np.where(done, rev, 0.0), s_out

    def take(self, idx):
        other = MicroflakeFiber.__new__(MicroflakeFiber)
        other.stddev = lanes(self.stddev, idx)
        other.axis = lanes(self.axis, idx)
        other._ln_norm = lanes(self._ln_norm, idx)
        other._row = self._row
        other._inv_s, other._q_scale, other._s_scalar = self._inv_s, self._q_scale, self._s_scalar
        # The frame depends on the axis only: shared when the axis is one constant row.
        other._fr = self._fr if other.axis.shape[0] == 1 else None
        return self._child(other)
