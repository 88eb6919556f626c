"""Statistics helpers for Monte Carlo tests (reusable by any test module).

Chi-square goodness of fit of a direction sampler against its pdf, following Mitsuba's
``chi2`` test: sampled directions are binned on a (cosθ, φ) grid (equal solid angle per cell),
expected counts come from numerically integrating pdf() over each cell (adaptive
Gauss–Legendre in cosθ and φ), cells with small expected counts are pooled, and the
p-value is compared with a significance level corrected for the number of tests (Šidák).

Samplers may fail (a microfacet reflection below the horizon, a killed sample): those samples
land in one extra "no direction" cell whose expected probability is 1 − ∫pdf, so the test also
checks that ∫pdf equals the fraction of successful samples.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

#: Family-wise significance level of all chi-square tests of the suite together.
SIGNIFICANCE = 0.01


def sidak(alpha: float, n_tests: int) -> float:
    """Per-test level such that n independent tests together have level alpha."""
    return 1.0 - (1.0 - alpha) ** (1.0 / max(n_tests, 1))


def spherical_directions(cos_t: np.ndarray, phi: np.ndarray) -> np.ndarray:
    s = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    return np.stack([s * np.cos(phi), s * np.sin(phi), cos_t], axis=-1)


@dataclass
class Grid:
    """A (cosθ, φ) grid over cosθ in [cos_lo, cos_hi] and φ in [0, 2π)."""

    n_cos: int = 16
    n_phi: int = 32
    cos_lo: float = -1.0
    cos_hi: float = 1.0

    def bin(self, w: np.ndarray) -> np.ndarray:
        """Counts (n_cos, n_phi) of unit directions w (rows); directions outside are an error."""
        c = w[:, 2]
        if np.any((c < self.cos_lo) | (c > self.cos_hi)):
            raise AssertionError("sampled direction outside the binned cosθ range")
        i = np.clip(((c - self.cos_lo) / (self.cos_hi - self.cos_lo) * self.n_cos).astype(int),
                    0, self.n_cos - 1)
        phi = np.mod(np.arctan2(w[:, 1], w[:, 0]), 2.0 * np.pi)
        j = np.clip((phi / (2.0 * np.pi) * self.n_phi).astype(int), 0, self.n_phi - 1)
        counts = np.zeros((self.n_cos, self.n_phi))
        np.add.at(counts, (i, j), 1.0)
        return counts

    def _cells(self, pdf, ci: np.ndarray, cj: np.ndarray, order: int, sub: int):
        """∫ pdf dω over cells (ci, cj): Gauss–Legendre, ``order`` nodes per dimension on each of
        sub × sub sub-cells. pdf maps (M, 3) unit directions to (M,). Also returns, per cell,
        whether any node had pdf > 0 and whether any had pdf == 0."""
        x, wt = np.polynomial.legendre.leggauss(order)
        dc = (self.cos_hi - self.cos_lo) / self.n_cos
        dp = 2.0 * np.pi / self.n_phi
        t = (np.arange(sub)[:, None] + 0.5 * (x[None, :] + 1.0)).ravel() / sub   # in [0, 1]
        w1 = np.tile(wt, sub) / (2.0 * sub)                                    # sums to 1
        out = np.zeros(ci.size)
        pos = np.zeros(ci.size, dtype=bool)
        zero = np.zeros(ci.size, dtype=bool)
        chunk = max(1, 400_000 // (t.size * t.size))
        for s0 in range(0, ci.size, chunk):
            a, b = ci[s0:s0 + chunk], cj[s0:s0 + chunk]
            cc = self.cos_lo + dc * (a[:, None] + t[None, :])
            pp = dp * (b[:, None] + t[None, :])
            C = np.broadcast_to(cc[:, :, None], (a.size, t.size, t.size))
            P = np.broadcast_to(pp[:, None, :], (a.size, t.size, t.size))
            v = np.asarray(pdf(spherical_directions(C.ravel(), P.ravel())), dtype=np.float64)
            v = v.reshape(a.size, t.size, t.size)
            out[s0:s0 + chunk] = np.einsum("kab,a,b->k", v, w1, w1) * dc * dp
            pos[s0:s0 + chunk] = (v > 0).any(axis=(1, 2))
            zero[s0:s0 + chunk] = (v <= 0).any(axis=(1, 2))
        return out, pos, zero

    def integrate(self, pdf, order: int = 4, tol: float = 1e-7, max_sub: int = 16,
                  hint: np.ndarray | None = None) -> np.ndarray:
        """∫ pdf dω over every cell, shape (n_cos, n_phi). Adaptive: a cell is split further
        (2, 4, ... sub-cells per side) until two successive rules agree within ``tol``
        (absolute, in probability) or max_sub is reached — pdfs with a narrow peak inside a
        cell need it. Cells near the edge of the pdf's support (a visibility or horizon cut,
        where quadrature converges slowly and can miss a sliver entirely) always go to max_sub:
        those with a zero node that are, or touch, a cell with a positive node or a cell where
        ``hint`` (e.g. the observed sample counts) is positive — a support narrower than the
        initial nodes (a sliver at the pole) is found that way."""
        ci, cj = np.meshgrid(np.arange(self.n_cos), np.arange(self.n_phi), indexing="ij")
        ci, cj = ci.ravel(), cj.ravel()
        prev, pos, zero = self._cells(pdf, ci, cj, order, 2)
        p2 = pos.reshape(self.n_cos, self.n_phi)
        if hint is not None:
            p2 = p2 | (np.asarray(hint).reshape(self.n_cos, self.n_phi) > 0)
        near = p2.copy()
        near[1:] |= p2[:-1]
        near[:-1] |= p2[1:]
        near |= np.roll(p2, 1, axis=1) | np.roll(p2, -1, axis=1)   # φ wraps around
        near = near.ravel()
        cut = zero & near
        out = prev.copy()
        todo = np.nonzero(p2.ravel() | cut)[0]
        prev = prev[todo]
        sub = 4
        while todo.size and sub <= max_sub:
            cur, _, _ = self._cells(pdf, ci[todo], cj[todo], order, sub)
            done = (np.abs(cur - prev) <= tol) & ~cut[todo]
            out[todo] = cur
            todo, prev = todo[~done], cur[~done]
            sub *= 2
        self.unconverged = int(todo.size)  # includes cut cells, which stop at max_sub
        return out.reshape(self.n_cos, self.n_phi)


@dataclass
class Chi2Result:
    statistic: float
    dof: int
    p_value: float
    integral: float          # ∫ pdf over the grid
    success_fraction: float  # fraction of samples that produced a direction
    quad_error: float        # bound on the quadrature error from cells that did not converge
    note: str = ""

    def __str__(self) -> str:
        return (f"chi2={self.statistic:.1f} dof={self.dof} p={self.p_value:.3g} "
                f"∫pdf={self.integral:.5f} success={self.success_fraction:.5f} "
                f"quad_err={self.quad_error:.1e} {self.note}")


def chi2_test(directions: np.ndarray, n_total: int, pdf, grid: Grid,
              min_expected: float = 5.0) -> Chi2Result:
    """Goodness of fit of ``directions`` (the successful samples out of ``n_total`` draws)
    against ``pdf``. Returns the statistic and p-value (pooled cells, "no direction" cell)."""
    observed = grid.bin(directions)
    # Quadrature accuracy: 0.01 expected samples per cell, far below the Poisson noise.
    prob = grid.integrate(pdf, tol=0.01 / n_total, hint=observed)
    quad_error = grid.unconverged * 0.01 / n_total
    if np.any(prob < -1e-12) or not np.all(np.isfinite(prob)):
        return Chi2Result(np.inf, 0, 0.0, float(prob.sum()), 0.0, quad_error, "negative/NaN pdf")
    prob = np.maximum(prob, 0.0)
    expected = prob.ravel() * n_total
    obs = observed.ravel()
    # The "no direction" cell: failed samples vs the pdf's missing mass.
    miss_p = max(0.0, 1.0 - prob.sum())
    expected = np.append(expected, miss_p * n_total)
    obs = np.append(obs, n_total - len(directions))
    # A sample where the pdf is 0 is an outright failure. (Checked at the samples themselves:
    # a cell the visible region only clips can integrate to ~0 by quadrature and still be hit.)
    at_samples = np.asarray(pdf(directions)) if len(directions) else np.ones(1)
    if np.any(~(at_samples > 0)):
        return Chi2Result(np.inf, 0, 0.0, float(prob.sum()), len(directions) / n_total,
                          quad_error, f"{int(np.sum(~(at_samples > 0)))} samples where the pdf is 0")
    # Pool cells with small expected counts (Mitsuba: merge until the pool reaches the minimum).
    order_idx = np.argsort(expected)
    e_sorted, o_sorted = expected[order_idx], obs[order_idx]
    small = e_sorted < min_expected
    pooled_e, pooled_o = e_sorted[small].sum(), o_sorted[small].sum()
    e_keep, o_keep = list(e_sorted[~small]), list(o_sorted[~small])
    if pooled_e > 0:
        if pooled_e < min_expected and e_keep:
            # too little to stand alone: merge into the smallest kept cell
            e_keep[0] += pooled_e
            o_keep[0] += pooled_o
        else:
            e_keep.append(pooled_e)
            o_keep.append(pooled_o)
    e_arr, o_arr = np.array(e_keep), np.array(o_keep)
    stat = float(np.sum((o_arr - e_arr) ** 2 / e_arr))
    dof = len(e_arr) - 1
    p = float(sps.chi2.sf(stat, dof)) if dof > 0 else 1.0
    return Chi2Result(stat, dof, p, float(prob.sum()), len(directions) / n_total, quad_error)


def mean_and_stderr(x: np.ndarray, axis: int = 0):
    """Sample mean and its standard error (estimated from the samples)."""
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[axis]
    return x.mean(axis=axis), x.std(axis=axis, ddof=1) / np.sqrt(n)
