"""Multiple importance sampling weights, for the bounce loop (kernels/integrator.py) and the
layered walks (kernels/layered/estimators.py) alike."""
from __future__ import annotations

from .jit import kernel


@kernel(error_model="numpy")
def power_heuristic(a, b):
    """Veach's power heuristic with β = 2 for one sample of each strategy: a²/(a² + b²), with
    0/0 → 0 (neither strategy could have made the sample)."""
    a2 = a * a
    den = a2 + b * b
    return a2 / den if den > 0.0 else 0.0
