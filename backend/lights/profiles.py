"""Angular emission profiles of area lights: radiance ∝ f(θ), θ = angle to the emitter's normal.

Profiles are normalised to keep the emitted power: the radiance is ``L0 · f(θ) / K`` with

    K = 2 ∫₀^{π/2} f(θ) cos θ sin θ dθ        (K = 1 for f ≡ 1)

so ``∫ L cos θ dω = π L0`` whatever the profile, as for a Lambertian emitter of radiance L0:
narrowing the beam concentrates the same power (as Cycles does for the area light ``spread``).
Profiles expose ``cos_max``/``tan_max`` (the cutoff: f = 0 beyond it) so samplers can skip the
parts of an emitter that cannot reach a point.
"""
from __future__ import annotations

import numpy as np

from .common import safe_div


class Lambertian:
    """f ≡ 1 on the front hemisphere (Blender's default spread of 180°)."""

    cos_max = 0.0
    tan_max = np.inf
    normalization = 1.0
    is_lambertian = True

    def __call__(self, cos_theta: np.ndarray) -> np.ndarray:
        return (np.asarray(cos_theta) > 0).astype(np.float64)


class CyclesSpread:
    """Blender/Cycles area light ``spread`` s (src/kernel/light/area.h, "soft-box grid").

    With a = s/2: f(θ) = max(0, 1 − tan θ / tan a) and K = (tan a − a) / tan a, i.e. the radiance
    is L0 · (tan a − tan θ)/(tan a − a) — Cycles' ``(tan_half_spread − tan θ) · normalize_spread``
    with ``normalize_spread = 1/(tan a − a)``. (Cycles replaces tan a − a by a³/3 below a = 0.05 in
    single precision, which is at most 0.1 % brighter; we keep the exact value.)
    """

    is_lambertian = False

    def __init__(self, spread: float):
        """``spread``: full angle in radians, in (0, π)."""
        a = 0.5 * float(spread)
        self.half = a
        self.tan_max = float(np.tan(a))
        self.cos_max = float(np.cos(a))
        if a < 1e-3:
            tan_minus_a = a ** 3 / 3.0 + 2.0 * a ** 5 / 15.0 + 17.0 * a ** 7 / 315.0
        else:
            tan_minus_a = self.tan_max - a
        self.normalization = tan_minus_a / self.tan_max

    def __call__(self, cos_theta: np.ndarray) -> np.ndarray:
        c = np.asarray(cos_theta, dtype=np.float64)
        tan_t = safe_div(np.sqrt(np.maximum(0.0, 1.0 - c * c)), c)
        return np.where(c > 0, np.maximum(0.0, 1.0 - tan_t / self.tan_max), 0.0)


class SmoothCone:
    """Directional area light: full within ``beam_width`` of the normal, none beyond
    ``cutoff_angle``, smoothstep in the angle in between:

        f(θ) = 1                       θ ≤ b
             = s²(3 − 2s), s = (c − θ)/(c − b)    b < θ < c
             = 0                       θ ≥ c
    """

    is_lambertian = False

    def __init__(self, cutoff: float, beam: float):
        """Angles in radians, 0 ≤ beam ≤ cutoff ≤ π/2, cutoff > 0."""
        self.cutoff = float(cutoff)
        self.beam = min(float(beam), self.cutoff)
        self.cos_max = float(np.cos(self.cutoff))
        self.tan_max = float(np.tan(self.cutoff)) if self.cutoff < 0.5 * np.pi else np.inf
        # K = sin² b + ∫_b^c f(θ) sin 2θ dθ; the integrand is smooth, 64-point Gauss-Legendre is
        # exact to rounding.
        k = np.sin(self.beam) ** 2
        if self.cutoff > self.beam:
            x, w = np.polynomial.legendre.leggauss(64)
            half = 0.5 * (self.cutoff - self.beam)
            theta = self.beam + half * (x + 1.0)
            k += half * float(np.sum(w * self._ramp(theta) * np.sin(2.0 * theta)))
        self.normalization = float(k)

    def _ramp(self, theta):
        s = np.clip((self.cutoff - theta) / (self.cutoff - self.beam), 0.0, 1.0)
        return s * s * (3.0 - 2.0 * s)

    def __call__(self, cos_theta: np.ndarray) -> np.ndarray:
        c = np.asarray(cos_theta, dtype=np.float64)
        theta = np.arccos(np.clip(c, -1.0, 1.0))
        if self.cutoff > self.beam:
            f = np.where(theta <= self.beam, 1.0, self._ramp(theta))
        else:
            f = (theta <= self.cutoff).astype(np.float64)
        return np.where(c > 0, f, 0.0)


class ConeTable:
    """Samples emission directions inside a profile's cutoff cone with density ∝ f(θ) cos θ
    (the shape of the emitted power), piecewise constant in μ = cos θ over ``bins`` bins.

    For a point whose whole cone footprint lies on the emitter this makes the NEE estimate
    nearly constant (radiance / pdf ≈ π L0 / cos θ); ``pdf(μ)`` is the exact solid-angle density.
    """

    def __init__(self, profile, bins: int = 256):
        from ..sampling.discrete import Discrete1D
        self.mu_lo = max(float(profile.cos_max), 0.0)
        self.bins = bins
        self.width = (1.0 - self.mu_lo) / bins
        x, w = np.polynomial.legendre.leggauss(8)
        left = self.mu_lo + np.arange(bins) * self.width
        mu = left[:, None] + 0.5 * self.width * (x[None, :] + 1.0)
        weights = (profile(mu.ravel()).reshape(mu.shape) * mu * w[None, :]).sum(axis=1)
        self.dist = Discrete1D(np.maximum(weights, 0.0))
        self.density = self.dist.pmf / (self.width * 2.0 * np.pi)   # per steradian

    def sample(self, u: np.ndarray):
        """u (n, 2) → (μ, φ, solid-angle pdf)."""
        k, _, rem = self.dist.sample(u[:, 0])
        mu = np.minimum(self.mu_lo + (k + rem) * self.width, 1.0)
        return mu, 2.0 * np.pi * u[:, 1], self.density[k]

    def pdf(self, mu: np.ndarray) -> np.ndarray:
        k = np.floor((mu - self.mu_lo) / self.width).astype(np.int64)
        inside = (mu >= self.mu_lo) & (mu <= 1.0)
        return np.where(inside, self.density[np.clip(k, 0, self.bins - 1)], 0.0)
