"""Vectorised error functions for the Beckmann distribution (numpy has none; scipy is not
available inside Blender).

``erfc`` uses the Chebyshev-fitted exponential form of Press et al., Numerical Recipes (2nd ed.,
§6.2, "erfcc"): fractional error below 1.2e-7 everywhere, no cancellation in the tails (what
the Beckmann masking term needs at steep angles). Accuracy is checked against ``math.erfc`` in
tests/test_materials_microfacet.py.
"""
from __future__ import annotations

import numpy as np

SQRT_PI = np.sqrt(np.pi)

# Numerical Recipes erfcc coefficients (published numbers), innermost last.
_NR = (-1.26551223, 1.00002368, 0.37409196, 0.09678418, -0.18628806,
       0.27886807, -1.13520398, 1.48851587, -0.82215223, 0.17087277)


def erfc(x):
    x = np.asarray(x, dtype=np.float64)
    z = np.abs(x)
    t = 1.0 / (1.0 + 0.5 * z)
    poly = _NR[-1]
    for c in _NR[-2::-1]:
        poly = c + t * poly
    # exp underflows to exactly 0 for z > ~27, which is the correct limit.
    ans = t * np.exp(-z * z + poly)
    return np.where(x >= 0, ans, 2.0 - ans)


def erf(x):
    return 1.0 - erfc(x)


def _erfcinv_upper(c):
    """y >= 0 with erfc(y) = c for c in (0, 1]."""
    c = np.clip(np.asarray(c, dtype=np.float64), 1e-300, 1.0)
    # Initial guess: Winitzki's closed-form approximation of erfinv (relative error ~2e-3).
    a = 0.147
    L = np.log(c * (2.0 - c))
    A = 2.0 / (np.pi * a) + 0.5 * L
    y = np.sqrt(np.maximum(0.0, np.sqrt(np.maximum(0.0, A * A - L / a)) - A))
    for _ in range(4):  # Newton on erfc(y) - c; erfc' = -2/√π e^{-y²}; quadratic convergence
        step = (erfc(y) - c) * (0.5 * SQRT_PI) * np.exp(np.minimum(y * y, 700.0))
        y = np.maximum(y + step, 0.0)
    return y


def erfinv_from_uniform(u):
    """erfinv(2u − 1) for u in [0, 1), i.e. a N(0, 1/2) variate, without cancellation near ±1."""
    u = np.asarray(u, dtype=np.float64)
    lower = u < 0.5
    c = np.where(lower, 2.0 * u, 2.0 * (1.0 - u))  # both exact in floating point
    y = _erfcinv_upper(c)
    return np.where(lower, -y, y)
