"""Phase functions of the angle between d_in and d_out: isotropic, Henyey–Greenstein, von Mises–Fisher,
Rayleigh.

All four are symmetric in (d_in, d_out) and depend only on cos θ = d_in·d_out, so they are
reciprocal, sampled exactly (weight 1) and have ``sigma_scale`` = 1. The per-lane maths is
compiled (backend/kernels/layered/phase.py); these classes hold the (per-lane or constant)
parameters.

Precision: 1 − cos θ and 1 + cos θ are formed as |d_in ∓ d_out|²/2, not from the dot product,
because the lobes of HG at g = 0.999 and vMF at κ = 1e4 are ~1e-3 to 1e-2 rad wide and 1 − cos θ
computed as 1 − dot loses digits there.
"""
from __future__ import annotations

import numpy as np

from ...kernels.layered import phase_layout as kp
from .base import Phase, lane_count, lanes, scalar_lanes, slot_rows

G_MAX = kp.G_MAX  # |g| clamp: pbrt-v4 issue #333 shows NaNs at g = ±1


class _Unparameterised(Phase):
    """A phase function without parameters, symmetric about 90° (mean cosine 0)."""

    def _bind_rows(self):
        return slot_rows(self.type_name)

    def mean_cosine(self):
        return np.zeros(())

    def take(self, idx):
        return self._child(type(self)())


class _OneScalar(Phase):
    """A phase function of one scalar parameter (the schema's slot ``a``), held in the attribute
    ``param`` names: () constant or (n,) per lane."""

    param = ""

    @property
    def n(self):
        return lane_count(getattr(self, self.param))

    def _bind_rows(self):
        return slot_rows(self.type_name, getattr(self, self.param))

    def take(self, idx):
        return self._child(type(self)(lanes(getattr(self, self.param), idx)))


class Isotropic(_Unparameterised):
    type_name = "isotropic"


class HenyeyGreenstein(_OneScalar):
    """p(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}); g > 0 scatters forward.

    ``g`` has shape () (constant) or (n,) (per lane); it is clamped to [−0.999, 0.999].
    """

    type_name = "hg"
    param = "g"

    def __init__(self, g):
        super().__init__()
        self.g = np.clip(scalar_lanes(g), -G_MAX, G_MAX)

    def mean_cosine(self):
        return self.g


class VonMisesFisher(_OneScalar):
    """p(cos θ) = κ exp(κ (cos θ − 1)) / (2π (1 − e^{−2κ})), centred on the forward direction.

    ``kappa`` ≥ 0 has shape () or (n,); κ = 0 is isotropic. Written with e^{κ(cos θ − 1)} so that
    κ = 1e4 neither overflows nor loses the lobe.
    """

    type_name = "vmf"
    param = "kappa"

    def __init__(self, kappa):
        super().__init__()
        self.kappa = np.maximum(scalar_lanes(kappa), 0.0)

    def mean_cosine(self):
        k = self.kappa
        small = k < 1e-4
        ks = np.where(small, 1.0, k)
        # coth κ − 1/κ, with coth κ = (1 + e^{−2κ}) / (1 − e^{−2κ}); series κ/3 near 0.
        coth = (1.0 + np.exp(-2.0 * ks)) / -np.expm1(-2.0 * ks)
        return np.where(small, k / 3.0, coth - 1.0 / ks)


class Rayleigh(_Unparameterised):
    """p(cos θ) = 3 (1 + cos²θ) / (16π): scattering by particles much smaller than the
    wavelength (unpolarised light); symmetric forward/backward, mean cosine 0."""

    type_name = "rayleigh"
