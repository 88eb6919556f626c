"""Discrete and piecewise-constant distributions (light selection, environment maps).

Construction (load time) is NumPy; sampling and densities loop the per-lane code of
``backend/kernels/discrete.py`` (its docstring has the conventions and the block layout) over
arrays, so these classes and the light kernels share one implementation.
"""
from __future__ import annotations

import numpy as np

from ..kernels import sampling_batch as _b
from ..kernels.discrete import layout_1d


class Discrete1D:
    """Pick index i with probability w[i] / sum(w). Weights must be finite and >= 0."""

    def __init__(self, weights: np.ndarray):
        w = np.asarray(weights, dtype=np.float64).ravel()
        if w.size == 0 or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError("Discrete1D needs a non-empty array of finite, non-negative weights")
        #: block: [cdf | pmf], the kernels' 1-D block (kernels/discrete.py)
        self.total, self.pmf, self.cdf, self.block = layout_1d(w)

    def __len__(self) -> int:
        return self.pmf.size

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Returns (index, probability, u remapped to [0, 1) within the chosen bin)."""
        u = np.ascontiguousarray(u, dtype=np.float64)
        flat = u.reshape(-1)
        idx = np.empty(flat.size, np.int64)
        p = np.empty(flat.size)
        u_rem = np.empty(flat.size)
        _b.sample_1d(self.block, self.pmf.size, flat, idx, p, u_rem)
        return idx.reshape(u.shape), p.reshape(u.shape), u_rem.reshape(u.shape)


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
        #: the kernels' 2-D block (kernels/discrete.py)
        self.block = np.ascontiguousarray(np.concatenate([
            self.density.ravel(), self.marginal.block, self.cond_cdf.ravel(), self.cond_pmf.ravel()]))

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """u (N, 2) -> (points (N, 2) in [0,1)^2 as (x=u, y=v), pdf (N,))."""
        u = np.ascontiguousarray(u, dtype=np.float64).reshape(-1, 2)
        xy = np.empty((u.shape[0], 2))
        pdf = np.empty(u.shape[0])
        _b.sample_2d(self.block, self.h, self.w, u, xy, pdf)
        return xy, pdf

    def pdf(self, xy: np.ndarray) -> np.ndarray:
        xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
        out = np.empty(xy.shape[0])
        _b.pdf_2d(self.block, self.h, self.w, xy, out)
        return out
