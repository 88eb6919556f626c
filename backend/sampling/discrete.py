"""Discrete and piecewise-constant distributions (light selection, environment maps)."""
from __future__ import annotations

import numpy as np


class Discrete1D:
    """Pick index i with probability w[i] / sum(w). Weights must be finite and >= 0."""

    def __init__(self, weights: np.ndarray):
        w = np.asarray(weights, dtype=np.float64).ravel()
        if w.size == 0 or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError("Discrete1D needs a non-empty array of finite, non-negative weights")
        total = w.sum()
        if total <= 0:
            w = np.ones_like(w)
            total = float(w.size)
        self.total = float(total)
        self.pmf = w / total
        self.cdf = np.concatenate([[0.0], np.cumsum(self.pmf)])
        self.cdf[-1] = 1.0

    def __len__(self) -> int:
        return self.pmf.size

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Returns (index, probability, u remapped to [0, 1) within the chosen bin)."""
        idx = np.searchsorted(self.cdf, u, side="right") - 1
        idx = np.clip(idx, 0, self.pmf.size - 1)
        # Zero-probability bins can only be hit at exact cdf ties: move to the next non-empty bin.
        p = self.pmf[idx]
        width = np.where(p > 0, p, 1.0)
        u_rem = np.clip((u - self.cdf[idx]) / width, 0.0, np.nextafter(1.0, 0.0))
        return idx, p, u_rem


class PiecewiseConstant2D:
    """Density over [0,1)^2 proportional to a (H, W) table (rows = v, columns = u).

    Sampling picks a row from the marginal, then a column from that row's conditional, then a
    uniform point inside the cell. ``pdf`` is w.r.t. area on the unit square.
    """

    def __init__(self, table: np.ndarray):
        f = np.asarray(table, dtype=np.float64)
        if f.ndim != 2 or not np.all(np.isfinite(f)) or np.any(f < 0):
            raise ValueError("PiecewiseConstant2D needs a finite, non-negative 2-D table")
        self.h, self.w = f.shape
        row_sums = f.sum(axis=1)
        total = row_sums.sum()
        if total <= 0:
            f = np.ones_like(f)
            row_sums = f.sum(axis=1)
            total = row_sums.sum()
        self.density = f * (self.h * self.w / total)  # mean 1 over the unit square
        self.marginal = Discrete1D(row_sums)
        safe = np.where(row_sums > 0, row_sums, 1.0)[:, None]
        cond = np.where(row_sums[:, None] > 0, f / safe, 1.0 / self.w)
        self.cond_cdf = np.concatenate([np.zeros((self.h, 1)), np.cumsum(cond, axis=1)], axis=1)
        self.cond_cdf[:, -1] = 1.0
        self.cond_pmf = cond
        # Row r's CDF shifted by r: one increasing array, so a single searchsorted serves all
        # lanes (no (N, W) temporaries for large environment maps).
        self._flat_cdf = (np.arange(self.h)[:, None] + self.cond_cdf).ravel()

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """u (N, 2) -> (points (N, 2) in [0,1)^2 as (x=u, y=v), pdf (N,))."""
        row, _, u_row = self.marginal.sample(u[:, 1])
        k = np.searchsorted(self._flat_cdf, row + u[:, 0], side="right") - 1
        col = np.clip(k - row * (self.w + 1), 0, self.w - 1)
        p = self.cond_pmf[row, col]
        frac = np.clip((u[:, 0] - self.cond_cdf[row, col]) / np.where(p > 0, p, 1.0),
                       0.0, np.nextafter(1.0, 0.0))
        x = (col + frac) / self.w
        y = (row + u_row) / self.h
        return np.stack([x, y], axis=-1), self.density[row, col]

    def pdf(self, xy: np.ndarray) -> np.ndarray:
        col = np.clip((xy[:, 0] * self.w).astype(np.int64), 0, self.w - 1)
        row = np.clip((xy[:, 1] * self.h).astype(np.int64), 0, self.h - 1)
        return self.density[row, col]
