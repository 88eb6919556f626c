"""Error functions for the Beckmann distribution, per lane (no SciPy inside Blender).

``erfc``: the Chebyshev-fitted exponential form of Press et al., Numerical Recipes (2nd ed.,
§6.2, "erfcc"): fractional error below 1.2e-7 everywhere and no cancellation in the tails, which
the Beckmann masking term needs at steep angles. ``erfinv_from_uniform(u)`` = erfinv(2u − 1)
without cancellation near ±1 (Winitzki's start, four Newton steps on erfc).
"""
from __future__ import annotations

import math

from .jit import kernel

SQRT_PI = math.sqrt(math.pi)

# Numerical Recipes erfcc coefficients (published numbers), innermost last.
NR = (-1.26551223, 1.00002368, 0.37409196, 0.09678418, -0.18628806,
      0.27886807, -1.13520398, 1.48851587, -0.82215223, 0.17087277)


@kernel
def erfc(x):
    z = abs(x)
    t = 1.0 / (1.0 + 0.5 * z)
    poly = 0.17087277
    poly = -0.82215223 + t * poly
    poly = 1.48851587 + t * poly
    poly = -1.13520398 + t * poly
    poly = 0.27886807 + t * poly
    poly = -0.18628806 + t * poly
    poly = 0.09678418 + t * poly
    poly = 0.37409196 + t * poly
    poly = 1.00002368 + t * poly
    poly = -1.26551223 + t * poly
    # exp underflows to exactly 0 for z > ~27: the correct limit.
    ans = t * math.exp(-z * z + poly)
    return ans if x >= 0.0 else 2.0 - ans


@kernel
def _erfcinv_upper(c):
    """y ≥ 0 with erfc(y) = c, c in (0, 1]."""
    c = min(max(c, 1e-300), 1.0)
    a = 0.147
    L = math.log(c * (2.0 - c))
    A = 2.0 / (math.pi * a) + 0.5 * L
    y = math.sqrt(max(0.0, math.sqrt(max(0.0, A * A - L / a)) - A))
    for _ in range(4):   # Newton on erfc(y) − c; erfc' = −2/√π e^{−y²}
        step = (erfc(y) - c) * (0.5 * SQRT_PI) * math.exp(min(y * y, 700.0))
        y = max(y + step, 0.0)
    return y


@kernel
def erfinv_from_uniform(u):
    """erfinv(2u − 1) for u in [0, 1): a N(0, 1/2) variate."""
    if u < 0.5:
        return -_erfcinv_upper(2.0 * u)
    return _erfcinv_upper(2.0 * (1.0 - u))
