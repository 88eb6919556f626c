"""Discrete and piecewise-constant 2-D distributions per lane (light selection, mesh-light
triangles, cone tables, environment maps).

Both live in flat float64 blocks (inside a light table's ``aux`` array, or on their own for the
NumPy wrappers in ``backend/sampling/discrete.py``, which build them at load time):

* 1-D over n bins, at ``off``:  [cdf (n + 1) | pmf (n)], cdf[0] = 0, cdf[n] = 1 exactly.
* 2-D over an (h, w) table (rows = y, columns = x), at ``off``:
  [density (h·w) | marginal 1-D block over rows (2h + 1) | conditional cdfs (h·(w + 1)) |
  conditional pmfs (h·w)]; ``density`` is the pdf on the unit square (mean 1).

Sampling a bin takes the largest i with cdf[i] ≤ u (NumPy's ``searchsorted(side="right") − 1``),
so a bin of zero probability is never chosen (its cdf equals the next bin's start), not even at
exact ties; the remapped number (u − cdf[i]) / pmf[i] is clamped to [0, 1) and can be reused.
"""
from __future__ import annotations

import numpy as np

from .jit import kernel

ONE_MINUS_EPS = float(np.nextafter(1.0, 0.0))   # largest double below 1


def layout_1d(weights: np.ndarray) -> tuple:
    """(total, pmf, cdf, block) of finite, non-negative ``weights`` (NumPy, at load time): the
    1-D block above; all-zero weights give the uniform distribution (total = n)."""
    w = np.asarray(weights, dtype=np.float64).ravel()
    total = float(w.sum())
    if total <= 0:
        w = np.ones_like(w)
        total = float(w.size)
    pmf = w / total
    cdf = np.concatenate([[0.0], np.cumsum(pmf)])
    cdf[-1] = 1.0
    return total, pmf, cdf, np.ascontiguousarray(np.concatenate([cdf, pmf]))


@kernel
def block_1d_size(n):
    return 2 * n + 1


@kernel
def block_2d_size(h, w):
    return h * w + 2 * h + 1 + h * (w + 1) + h * w


@kernel
def upper_bound(a, lo, hi, x):
    """First index i in [lo, hi) with a[i] > x (hi if none); a sorted ascending."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] <= x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@kernel
def lower_bound(a, lo, hi, x):
    """First index i in [lo, hi) with a[i] ≥ x (hi if none); a sorted ascending."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@kernel
def sample_1d(a, off, n, u):
    """(bin, its probability, u remapped to [0, 1) within the bin) of the 1-D block at ``off``."""
    k = upper_bound(a, off, off + n + 1, u) - 1 - off
    if k < 0:
        k = 0
    elif k > n - 1:
        k = n - 1
    p = a[off + n + 1 + k]
    width = p if p > 0.0 else 1.0
    r = (u - a[off + k]) / width
    if r < 0.0:
        r = 0.0
    elif r > ONE_MINUS_EPS:
        r = ONE_MINUS_EPS
    return k, p, r


@kernel
def pmf_1d(a, off, n, k):
    return a[off + n + 1 + k]


@kernel
def sample_2d(a, off, h, w, u0, u1):
    """(x, y, pdf): a row from the marginal with u1, a column of that row with u0, then a
    uniform point in the cell; pdf per unit area of [0, 1)²."""
    marg = off + h * w
    ccdf = marg + 2 * h + 1
    cpmf = ccdf + h * (w + 1)
    row, _, u_row = sample_1d(a, marg, h, u1)
    base = ccdf + row * (w + 1)
    col = upper_bound(a, base, base + w + 1, u0) - 1 - base
    if col < 0:
        col = 0
    elif col > w - 1:
        col = w - 1
    p = a[cpmf + row * w + col]
    frac = (u0 - a[base + col]) / (p if p > 0.0 else 1.0)
    if frac < 0.0:
        frac = 0.0
    elif frac > ONE_MINUS_EPS:
        frac = ONE_MINUS_EPS
    return (col + frac) / w, (row + u_row) / h, a[off + row * w + col]


@kernel
def pdf_2d(a, off, h, w, x, y):
    """Density at (x, y) in [0, 1)² (the cell's; points outside are clamped to the border)."""
    xf = x * w
    yf = y * h
    col = 0 if not xf > 0.0 else (w - 1 if xf >= w else int(xf))   # NaN → 0
    row = 0 if not yf > 0.0 else (h - 1 if yf >= h else int(yf))
    return a[off + row * w + col]
