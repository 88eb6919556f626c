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

from ...kernels.layered import phase_layout as _kp
from ...mathutil import dot
from .base import Phase, lane_count, lanes, scalar_lanes, slot_rows, unit_or, vector_lanes

S_MIN, S_MAX = _kp.S_MIN, _kp.S_MAX   # stddev range (clamped); Mitsuba's fiber table spans 4e-8 … 4
MAX_ROUNDS = 128           # rejection cap per sample (rounds of the former NumPy sampler; the
EXTRA = 4                  # per-lane sampler draws 1 + (MAX_ROUNDS − 1)·EXTRA candidates at most)
UNIFORM_ABOVE = _kp.UNIFORM_ABOVE  # stddev above which x is proposed uniformly (better acceptance)

# Table layout: rows uniform in ln s, columns uniform in q; one ghost row/column on each side
# so the 4-point stencil never leaves the table (σ is even in θ and in θ − π/2, so ghost
# columns are just evaluated at |θ| or π − θ).
_LN_S0, _LN_S1 = math.log(S_MIN), math.log(S_MAX)
_ROWS = _kp.ROWS
_COLS = _kp.COLS
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


@lru_cache(maxsize=1)
def kernel_table() -> np.ndarray:
    """The table as the compiled code reads it (kernels/layered/phase.py ``FT``): the ghosted σ
    rows, then the ln N(s) row."""
    sigma, ln_norm = _table()
    return np.ascontiguousarray(np.vstack([sigma, ln_norm[None, :]]), dtype=np.float64)


# ------------------------------------------------------------------------------ phase
class MicroflakeFiber(Phase):
    """Guo et al.'s fiber microflake phase. ``stddev`` () or (n,); ``orientation`` (3,), (1, 3) or
    (n, 3) fiber axes in the layer frame (normalised here; a zero axis falls back to +x). The
    per-lane maths (σ lookup, exact rejection sampler) is compiled:
    backend/kernels/layered/phase.py."""

    type_name = "microflake"
    directional = True

    def __init__(self, stddev, orientation):
        super().__init__()
        self.stddev = clamp_stddev(scalar_lanes(stddev))
        self.axis = unit_or(vector_lanes(orientation), [1.0, 0.0, 0.0])
        self._ln_norm = ln_gauss_norm(self.stddev)

    @property
    def n(self):
        return lane_count(self.stddev, self.axis)

    def _bind_rows(self):
        return slot_rows(self.type_name, self.stddev, self.axis, kernel_table())

    def table(self) -> np.ndarray:
        return kernel_table()

    def _max_candidates(self) -> int:
        return 1 + (MAX_ROUNDS - 1) * EXTRA

    def distribution(self, m: np.ndarray) -> np.ndarray:
        """D(m), normalised to 1 over the sphere."""
        x = dot(m, self.axis)
        s = self.stddev
        return np.exp(-x * x / (2.0 * s * s) - self._ln_norm) / (2.0 * np.pi)

    def take(self, idx):
        other = MicroflakeFiber.__new__(MicroflakeFiber)
        other.stddev = lanes(self.stddev, idx)
        other.axis = lanes(self.axis, idx)
        other._ln_norm = lanes(self._ln_norm, idx)
        return self._child(other)
