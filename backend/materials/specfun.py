"""Error functions on arrays for the Beckmann distribution (no SciPy inside Blender): NumPy
ufuncs over the per-lane code in ``backend/kernels/specfun.py`` (Numerical Recipes' erfcc,
fractional error below 1.2e-7, no cancellation in the tails)."""
from __future__ import annotations

import numpy as np

from ..kernels.specfun import NR as _NR
from ..kernels.specfun import SQRT_PI
from ..kernels.ufuncs import erfc, erfinv_from_uniform

__all__ = ["SQRT_PI", "_NR", "erf", "erfc", "erfinv_from_uniform"]


def erf(x):
    return 1.0 - erfc(np.asarray(x, dtype=np.float64))
