"""Angular emission profiles of area lights per lane: radiance ∝ f(θ), θ = angle to the normal.

Profiles are normalised to keep the emitted power: the radiance is ``L0 · f(θ) / K`` with

    K = 2 ∫₀^{π/2} f(θ) cos θ sin θ dθ        (K = 1 for f ≡ 1)

so ``∫ L cos θ dω = π L0`` whatever the profile, as for a Lambertian emitter of radiance L0:
narrowing the beam concentrates the same power (as Cycles does for the area light ``spread``).
K is computed at load time (``backend/lights/profiles.py``); the kernels see f and the cutoff.

* LAMBERTIAN: f ≡ 1 on the front hemisphere (Blender's default spread of 180°).
* SPREAD — Blender/Cycles area light ``spread`` s (src/kernel/light/area.h, "soft-box grid"):
  with a = s/2, f(θ) = max(0, 1 − tan θ / tan a); K = (tan a − a)/tan a, i.e. the radiance is
  L0 · (tan a − tan θ)/(tan a − a), Cycles' ``(tan_half_spread − tan θ) · normalize_spread``.
* SMOOTH_CONE — the directional area light: full within ``beam_width`` b of the normal, none
  beyond ``cutoff_angle`` c, smoothstep in the angle in between:
      f(θ) = 1 (θ ≤ b);  s²(3 − 2s), s = (c − θ)/(c − b) (b < θ < c);  0 (θ ≥ c).

Cone table (``ConeTable`` at load time): emission directions inside the cutoff cone sampled with
density ∝ f(θ) cos θ, piecewise constant in μ = cos θ over ``bins`` equal bins of [μ_lo, 1]; block
at ``off`` in ``aux``: a 1-D distribution (discrete.py) then the per-bin density per steradian.
For a point whose whole cone footprint lies on the emitter this makes the NEE estimate nearly
constant (radiance / pdf ≈ π L0 / cos θ).
"""
from __future__ import annotations

import math

from ..discrete import block_1d_size, sample_1d
from ..jit import kernel

LAMBERTIAN = 0
SPREAD = 1
SMOOTH_CONE = 2


@kernel
def evaluate(kind, tan_max, cutoff, beam, cos_theta):
    """f(θ) for cos θ (0 behind the emitter). ``tan_max`` = tan(spread/2) (SPREAD); ``cutoff`` and
    ``beam`` in radians (SMOOTH_CONE)."""
    c = cos_theta
    if not c > 0.0:
        return 0.0
    if kind == LAMBERTIAN:
        return 1.0
    if kind == SPREAD:
        tan_t = math.sqrt(max(0.0, 1.0 - c * c)) / c
        return max(0.0, 1.0 - tan_t / tan_max)
    theta = math.acos(min(c, 1.0))
    if cutoff > beam:
        if theta <= beam:
            return 1.0
        s = min(max((cutoff - theta) / (cutoff - beam), 0.0), 1.0)
        return s * s * (3.0 - 2.0 * s)
    return 1.0 if theta <= cutoff else 0.0


@kernel
def cone_sample(aux, off, bins, mu_lo, width, u0, u1):
    """(μ = cos θ of the emission direction, φ, solid-angle pdf)."""
    k, _, rem = sample_1d(aux, off, bins, u0)
    mu = min(mu_lo + (k + rem) * width, 1.0)
    return mu, 2.0 * math.pi * u1, aux[off + block_1d_size(bins) + k]


@kernel
def cone_pdf(aux, off, bins, mu_lo, width, mu):
    if not (mu >= mu_lo and mu <= 1.0):
        return 0.0
    k = int(math.floor((mu - mu_lo) / width))
    k = min(max(k, 0), bins - 1)
    return aux[off + block_1d_size(bins) + k]
