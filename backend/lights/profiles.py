"""Angular emission profiles of area lights: radiance ∝ f(θ), θ = angle to the emitter's normal.

Profiles are normalised to keep the emitted power: the radiance is ``L0 · f(θ) / K`` with

    K = 2 ∫₀^{π/2} f(θ) cos θ sin θ dθ        (K = 1 for f ≡ 1)

so ``∫ L cos θ dω = π L0`` whatever the profile, as for a Lambertian emitter of radiance L0:
narrowing the beam concentrates the same power (as Cycles does for the area light ``spread``).
Profiles expose ``cos_max``/``tan_max`` (the cutoff: f = 0 beyond it) so samplers can skip the
parts of an emitter that cannot reach a point. f itself is per-lane code
(``backend/kernels/lights/profiles.py``, which has the formulas); these classes hold the
parameters, compute K at load time and evaluate f on arrays through the compiled code.
"""
from __future__ import annotations

import numpy as np

from ..kernels.lights import area as _ka
from ..kernels.lights import batch as _batch
from ..kernels.lights import profiles as _kp


class _Profile:
    code = _kp.LAMBERTIAN
    tan_max = np.inf
    _spread_tan = 0.0
    _cutoff = 0.0
    _beam = 0.0

    def __call__(self, cos_theta: np.ndarray) -> np.ndarray:
        c = np.asarray(cos_theta, dtype=np.float64)
        flat = np.ascontiguousarray(c).reshape(-1)
        out = np.empty(flat.size)
        _batch.profile_eval(self.code, self._spread_tan, self._cutoff, self._beam, flat, out)
        return out.reshape(c.shape)

    def pack(self, row) -> None:
        """The profile's columns of an area light row (kernels/lights/area.py)."""
        row.i[_ka.I_PROFILE] = self.code
        row.f[_ka.A_TAN_MAX] = self.tan_max
        row.f[_ka.A_SPREAD_TAN] = self._spread_tan
        row.f[_ka.A_CUTOFF] = self._cutoff
        row.f[_ka.A_BEAM] = self._beam


class Lambertian(_Profile):
    """f ≡ 1 on the front hemisphere (Blender's default spread of 180°)."""

    cos_max = 0.0
    normalization = 1.0
    is_lambertian = True


class CyclesSpread(_Profile):
    """Blender/Cycles area light ``spread`` s (src/kernel/light/area.h, "soft-box grid").

    With a = s/2: f(θ) = max(0, 1 − tan θ / tan a) and K = (tan a − a) / tan a, i.e. the radiance
    is L0 · (tan a − tan θ)/(tan a − a) — Cycles' ``(tan_half_spread − tan θ) · normalize_spread``
    with ``normalize_spread = 1/(tan a − a)``. (Cycles replaces tan a − a by a³/3 below a = 0.05 in
    single precision, which is at most 0.1 % brighter; we keep the exact value.)
    """

    code = _kp.SPREAD
    is_lambertian = False

    def __init__(self, spread: float):
        """``spread``: full angle in radians, in (0, π)."""
        a = 0.5 * float(spread)
        self.half = a
        self.tan_max = float(np.tan(a))
        self.cos_max = float(np.cos(a))
        self._spread_tan = self.tan_max
        if a < 1e-3:
            # tan a − a by its series: the difference would lose all digits to cancellation
            tan_minus_a = a ** 3 / 3.0 + 2.0 * a ** 5 / 15.0 + 17.0 * a ** 7 / 315.0
        else:
            tan_minus_a = self.tan_max - a
        self.normalization = tan_minus_a / self.tan_max


class SmoothCone(_Profile):
    """Directional area light: full within ``beam_width`` of the normal, none beyond
    ``cutoff_angle``, smoothstep in the angle in between:

        f(θ) = 1                       θ ≤ b
             = s²(3 − 2s), s = (c − θ)/(c − b)    b < θ < c
             = 0                       θ ≥ c
    """

    code = _kp.SMOOTH_CONE
    is_lambertian = False

    def __init__(self, cutoff: float, beam: float):
        """Angles in radians, 0 ≤ beam ≤ cutoff ≤ π/2, cutoff > 0."""
        self.cutoff = float(cutoff)
        self.beam = min(float(beam), self.cutoff)
        self._cutoff, self._beam = self.cutoff, self.beam
        self.cos_max = float(np.cos(self.cutoff))
        self.tan_max = float(np.tan(self.cutoff)) if self.cutoff < 0.5 * np.pi else np.inf
        # K = sin² b + ∫_b^c f(θ) sin 2θ dθ; the integrand is smooth, 64-point Gauss-Legendre is
        # exact to rounding.
        k = np.sin(self.beam) ** 2
        if self.cutoff > self.beam:
            x, w = np.polynomial.legendre.leggauss(64)
            half = 0.5 * (self.cutoff - self.beam)
            theta = self.beam + half * (x + 1.0)
            k += half * float(np.sum(w * self(np.cos(theta)) * np.sin(2.0 * theta)))
        self.normalization = float(k)


class ConeTable:
    """Samples emission directions inside a profile's cutoff cone with density ∝ f(θ) cos θ
    (the shape of the emitted power), piecewise constant in μ = cos θ over ``bins`` bins.

    Built here (load time); sampled per lane by ``backend/kernels/lights/profiles.py``
    (``cone_sample``/``cone_pdf``), whose block layout ``block`` follows: a 1-D distribution over
    the bins, then the density per steradian of each bin. ``pdf(μ)`` is the exact solid-angle
    density of ``sample``.
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
        self.block = np.ascontiguousarray(np.concatenate([self.dist.block, self.density]))

    def sample(self, u: np.ndarray):
        """u (n, 2) → (μ, φ, solid-angle pdf)."""
        u = np.ascontiguousarray(u, dtype=np.float64).reshape(-1, 2)
        mu, phi, pdf = (np.empty(u.shape[0]) for _ in range(3))
        _batch.cone_sample(self.block, self.bins, self.mu_lo, self.width, u, mu, phi, pdf)
        return mu, phi, pdf

    def pdf(self, mu: np.ndarray) -> np.ndarray:
        mu = np.ascontiguousarray(mu, dtype=np.float64).reshape(-1)
        out = np.empty(mu.size)
        _batch.cone_pdf(self.block, self.bins, self.mu_lo, self.width, mu, out)
        return out
