"""Phase functions of the angle between d_in and d_out: isotropic, Henyey–Greenstein, von Mises–Fisher.

All three are symmetric in (d_in, d_out) and depend only on cos θ = d_in·d_out, so they are
reciprocal, sampled exactly (weight 1) and have ``sigma_scale`` = 1.

Precision: 1 − cos θ and 1 + cos θ are formed as |d_in ∓ d_out|²/2, not from the dot product,
because the lobes of HG at g = 0.999 and vMF at κ = 1e4 are ~1e-3 to 1e-2 rad wide and 1 − cos θ
computed as 1 − dot loses digits there.
"""
from __future__ import annotations

import numpy as np

from ...mathutil import dot
from .base import Phase, PhaseSample, around, around3, lane_count, lanes, scalar_lanes

INV_4PI = 0.25 / np.pi
G_MAX = 0.999  # |g| clamp: pbrt-v4 issue #333 shows NaNs at g = ±1


def one_minus_cos(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = a - b
    return 0.5 * dot(d, d)


def one_plus_cos(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = a + b
    return 0.5 * dot(d, d)


class Isotropic(Phase):
    type_name = "isotropic"

    def eval(self, d_in, d_out):
        return np.full(d_in.shape[0], INV_4PI)

    def connect(self, a, b, s_a=None, s_b=None):
        v = np.full(a.shape[1], INV_4PI)
        return v, v

    def sample(self, d_in, rng):
        n = d_in.shape[0]
        u = rng.random((n, 2))
        z = 1.0 - 2.0 * u[:, 0]
        r = np.sqrt(np.maximum(0.0, (1.0 - z) * (1.0 + z)))
        phi = 2.0 * np.pi * u[:, 1]
        d = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
        return PhaseSample(d, np.ones(n), np.full(n, INV_4PI))

    def sample3(self, d_in, rng, s_in=None):
        m = d_in.shape[1]
        u = rng.random((2, m))
        z = 1.0 - 2.0 * u[0]
        r = np.sqrt(np.maximum(0.0, (1.0 - z) * (1.0 + z)))
        phi = 2.0 * np.pi * u[1]
        p = np.full(m, INV_4PI)
        return np.stack([r * np.cos(phi), r * np.sin(phi), z]), np.ones(m), p, p, None

    def mean_cosine(self):
        return np.zeros(())

    def take(self, idx):
        return self._child(Isotropic())


class HenyeyGreenstein(Phase):
    """p(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}); g > 0 scatters forward.

    ``g`` has shape () (constant) or (n,) (per lane); it is clamped to [−0.999, 0.999].
    """

    type_name = "hg"

    def __init__(self, g):
        super().__init__()
        self.g = np.clip(scalar_lanes(g), -G_MAX, G_MAX)

    @property
    def n(self):
        return lane_count(self.g)

    def eval(self, d_in, d_out):
        g = self.g
        # 1 + g² − 2g cos θ, written so that neither branch cancels: (1 − g)² + 2g(1 − cos) for g ≥ 0,
        # (1 + g)² − 2g(1 + cos) for g < 0; both terms are then non-negative.
        denom = np.where(g >= 0, (1.0 - g) ** 2 + 2.0 * g * one_minus_cos(d_in, d_out),
                         (1.0 + g) ** 2 - 2.0 * g * one_plus_cos(d_in, d_out))
        # denom ≥ (1 − |g|)² ≥ 1e-6 by the clamp: no division guard needed.
        return (1.0 - g * g) * INV_4PI / (denom * np.sqrt(denom))

    def connect(self, a, b, s_a=None, s_b=None):
        # Reciprocal: both densities are the value. With a, b pointing away from the scattering
        # point, 1 − cos θ = 1 + a·b = |a + b|²/2 and 1 + cos θ = |a − b|²/2 (precise forms).
        g = self.g
        if g.ndim == 0 and g >= 0:
            x, y, z = a[0] + b[0], a[1] + b[1], a[2] + b[2]
            denom = (1.0 - g) ** 2 + g * (x * x + y * y + z * z)
        else:
            s = 0.5 * ((a[0] + b[0]) ** 2 + (a[1] + b[1]) ** 2 + (a[2] + b[2]) ** 2)
            d = 0.5 * ((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)
            denom = np.where(g >= 0, (1.0 - g) ** 2 + 2.0 * g * s, (1.0 + g) ** 2 - 2.0 * g * d)
        v = (1.0 - g * g) * INV_4PI / (denom * np.sqrt(denom))
        return v, v

    def sample(self, d_in, rng):
        n = d_in.shape[0]
        g = np.broadcast_to(self.g, (n,))
        u = rng.random((n, 2))
        b = 1.0 - 2.0 * u[:, 0]  # in (−1, 1]
        # Inverse CDF of HG, rearranged so that g = 0 needs no special case: with a = 1 + g b,
        #   1 − cos θ = (1 − g)² (1 − b) (1 + g + a) / (2a²),  1 + cos θ = (1 + g)² (1 + b) (1 − g + a) / (2a²).
        # (Both follow from the textbook form cos θ = (1 + g² − ((1 − g²)/(1 + g b))²)/(2g).)
        a = 1.0 + g * b  # ≥ 1 − |g| ≥ 1e-3
        inv = 0.5 / (a * a)
        omc = (1.0 - g) ** 2 * (1.0 - b) * (1.0 + g + a) * inv
        opc = (1.0 + g) ** 2 * (1.0 + b) * (1.0 - g + a) * inv
        cos_t = np.clip(0.5 * (opc - omc), -1.0, 1.0)
        sin_t = np.sqrt(np.maximum(omc * opc, 0.0))
        d = around(d_in, cos_t, sin_t, 2.0 * np.pi * u[:, 1])
        return PhaseSample(d, np.ones(n), self.eval(d_in, d))

    def sample3(self, d_in, rng, s_in=None):
        # ``sample`` on (3, m), with the density from the sampled angle: 1 + g² − 2g cos θ = a⁻²(1 − g²)²
        # by the inverse CDF (a = 1 + g b), so p = (1 − g²)/(4π) · a³/(1 − g²)³ = a³/(4π (1 − g²)²).
        m = d_in.shape[1]
        g = self.g
        u = rng.random((2, m))
        b = 1.0 - 2.0 * u[0]
        a = 1.0 + g * b
        inv = 0.5 / (a * a)
        omc = (1.0 - g) ** 2 * (1.0 - b) * (1.0 + g + a) * inv
        opc = (1.0 + g) ** 2 * (1.0 + b) * (1.0 - g + a) * inv
        cos_t = np.clip(0.5 * (opc - omc), -1.0, 1.0)
        sin_t = np.sqrt(np.maximum(omc * opc, 0.0))
        d = around3(d_in, cos_t, sin_t, 2.0 * np.pi * u[1])
        one_g2 = 1.0 - g * g
        p = a * a * a * (INV_4PI / (one_g2 * one_g2))
        return d, np.ones(m), p, p, None

    def mean_cosine(self):
        return self.g

    def take(self, idx):
        return self._child(HenyeyGreenstein(lanes(self.g, idx)))


class VonMisesFisher(Phase):
    """p(cos θ) = κ exp(κ (cos θ − 1)) / (2π (1 − e^{−2κ})), centred on the forward direction.

    ``kappa`` ≥ 0 has shape () or (n,); κ = 0 is isotropic. Written with e^{κ(cos θ − 1)} so that
    κ = 1e4 neither overflows nor loses the lobe.
    """

    type_name = "vmf"

    def __init__(self, kappa):
        super().__init__()
        self.kappa = np.maximum(scalar_lanes(kappa), 0.0)

    @property
    def n(self):
        return lane_count(self.kappa)

    def _norm(self):
        k = self.kappa
        small = k < 1e-8
        # κ / (1 − e^{−2κ}) → 1/2 as κ → 0.
        return np.where(small, 0.5, k / np.where(small, 1.0, -np.expm1(-2.0 * k))) / (2.0 * np.pi)

    def eval(self, d_in, d_out):
        return self._norm() * np.exp(-self.kappa * one_minus_cos(d_in, d_out))

    def connect(self, a, b, s_a=None, s_b=None):
        # 1 − cos θ = |a + b|²/2 for directions pointing away from the scattering point.
        omc = 0.5 * ((a[0] + b[0]) ** 2 + (a[1] + b[1]) ** 2 + (a[2] + b[2]) ** 2)
        v = self._norm() * np.exp(-self.kappa * omc)
        return v, v

    def sample(self, d_in, rng):
        n = d_in.shape[0]
        k = np.broadcast_to(self.kappa, (n,))
        u = rng.random((n, 2))
        small = k < 1e-8
        ks = np.where(small, 1.0, k)
        # Inverse CDF: 1 − cos θ = −log(1 + u (e^{−2κ} − 1)) / κ, u ∈ [0, 1); 2u for κ → 0.
        omc = np.where(small, 2.0 * u[:, 0], -np.log1p(u[:, 0] * np.expm1(-2.0 * ks)) / ks)
        omc = np.clip(omc, 0.0, 2.0)
        cos_t = 1.0 - omc
        sin_t = np.sqrt(omc * (2.0 - omc))
        d = around(d_in, cos_t, sin_t, 2.0 * np.pi * u[:, 1])
        return PhaseSample(d, np.ones(n), self.eval(d_in, d))

    def mean_cosine(self):
        k = self.kappa
        small = k < 1e-4
        ks = np.where(small, 1.0, k)
        # coth κ − 1/κ, with coth κ = (1 + e^{−2κ}) / (1 − e^{−2κ}); series κ/3 near 0.
        coth = (1.0 + np.exp(-2.0 * ks)) / -np.expm1(-2.0 * ks)
        return np.where(small, k / 3.0, coth - 1.0 / ks)

    def take(self, idx):
        return self._child(VonMisesFisher(lanes(self.kappa, idx)))
