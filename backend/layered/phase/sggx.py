"""SGGX specular microflake phase function (Heitz, Dupuy, Crassin, Dachsbacher 2015).

The flakes are the normals of an ellipsoid described by a symmetric positive-definite matrix S
(the ellipsoid {x : xᵀ S x = 1}):

    D(m) = 1 / (π √det S (mᵀ S⁻¹ m)²),     σ(ω) = √(ωᵀ S ω)  (projected area, one side),
    p(d_in → d_out) = D(h) / (4 σ(d_in)),  h = normalise(−d_in + d_out).

For S = I this is the isotropic phase 1/(4π) with σ = 1, so ``sigma_scale`` = σ(ω) and the medium's
``sigma_t`` is the extinction of the S = I medium. (Heitz's σ counts one flake side; D integrates
to 4 over the sphere. Written with the two-sided σ2 = σ/2 and D/4 this is the same D/(2σ2) form
as the fiber phase.) Not reciprocal by itself: σ(a) p(a → b) = σ(b) p(−b → −a).

Parameterisation chosen for artists (see docs/materials.md):
* ``fiber``  (axis t, roughness α):  S = α² t tᵀ + (I − t tᵀ) — thin fibers along t; light along t
  sees their cross-section (σ = α), light across them sees σ = 1.
* ``flake``  (normal n, roughness α): S = n nᵀ + α² (I − n nᵀ) — platelets facing n; σ = 1 along n.
* an explicit matrix (Sxx, Syy, Szz, Sxy, Sxz, Syz).
α ∈ [1e-3, 1] (clamped); α = 1 is isotropic.

Visible-normal sampling, derived from the ellipsoid picture: with S = B Bᵀ (Cholesky, B lower
triangular) the ellipsoid is x = B⁻ᵀ u for unit u, its normal at u is ∝ B u, and rays along ωi
become rays along Bᵀ ωi in u-space. Points uniform in projected area on the visible half of the
unit sphere are cosine-distributed about Bᵀ ωi, so m = normalise(B u) with u cosine-distributed
about normalise(Bᵀ ωi) has density D(m)⟨ωi, m⟩/σ(ωi); reflecting ωi = −d_in about m gives p
exactly (weight 1).
"""
from __future__ import annotations

import numpy as np

from ...mathutil import dot
from .base import Phase, PhaseSample, around, lane_count, lanes, unit_or, vector_lanes

ROUGHNESS_MIN = 1e-3


def preset_matrix(kind: str, axis, roughness) -> np.ndarray:
    """S as (k, 6) = (Sxx, Syy, Szz, Sxy, Sxz, Syz) for ``kind`` "fiber" or "flake".

    ``axis`` (3,), (1, 3) or (k, 3) (normalised here); ``roughness`` () or (k,)."""
    a = unit_or(vector_lanes(axis), [0.0, 0.0, 1.0])
    r = np.clip(np.asarray(roughness, dtype=np.float64), ROUGHNESS_MIN, 1.0)
    r2 = (r * r).reshape(-1, 1) if r.ndim else r * r
    # fiber: S = r² aaᵀ + (I − aaᵀ) = I + (r² − 1) aaᵀ;  flake: S = aaᵀ + r²(I − aaᵀ) = r² I + (1 − r²) aaᵀ.
    iso, outer = (1.0, r2 - 1.0) if kind == "fiber" else (r2, 1.0 - r2)
    ax, ay, az = a[:, 0:1], a[:, 1:2], a[:, 2:3]
    s = np.concatenate([iso + outer * ax * ax, iso + outer * ay * ay, iso + outer * az * az,
                        outer * ax * ay, outer * ax * az, outer * ay * az], axis=1)
    return s


def is_positive_definite(s6) -> bool:
    s6 = np.asarray(s6, dtype=np.float64).reshape(6)
    m = np.array([[s6[0], s6[3], s6[4]], [s6[3], s6[1], s6[5]], [s6[4], s6[5], s6[2]]])
    return bool(np.all(np.linalg.eigvalsh(m) > 0))


def cholesky(s6: np.ndarray) -> np.ndarray:
    """Lower-triangular B with S = B Bᵀ, returned as (k, 6) = (B00, B10, B11, B20, B21, B22).

    Pivots are floored at 1e-300 so a (rejected-by-the-parser) singular S cannot make NaNs."""
    sxx, syy, szz, sxy, sxz, syz = (s6[:, i] for i in range(6))
    tiny = 1e-300
    b00 = np.sqrt(np.maximum(sxx, tiny))
    b10 = sxy / b00
    b20 = sxz / b00
    b11 = np.sqrt(np.maximum(syy - b10 * b10, tiny))
    b21 = (syz - b20 * b10) / b11
    b22 = np.sqrt(np.maximum(szz - b20 * b20 - b21 * b21, tiny))
    return np.stack([b00, b10, b11, b20, b21, b22], axis=1)


class SGGX(Phase):
    """SGGX phase with matrix ``s6`` of shape (6,), (1, 6) or (n, 6) (see module docstring)."""

    type_name = "sggx"
    directional = True

    def __init__(self, s6):
        super().__init__()
        s6 = np.asarray(s6, dtype=np.float64)
        self.s6 = s6.reshape(1, 6) if s6.size == 6 else s6.reshape(-1, 6)
        self.b = cholesky(self.s6)

    @classmethod
    def fiber(cls, axis, roughness) -> "SGGX":
        return cls(preset_matrix("fiber", axis, roughness))

    @classmethod
    def flake(cls, normal, roughness) -> "SGGX":
        return cls(preset_matrix("flake", normal, roughness))

    @property
    def n(self):
        return lane_count(self.s6)

    def _bt(self, w: np.ndarray) -> np.ndarray:
        """Bᵀ w (rows)."""
        b = self.b
        return np.stack([b[:, 0] * w[:, 0] + b[:, 1] * w[:, 1] + b[:, 3] * w[:, 2],
                         b[:, 2] * w[:, 1] + b[:, 4] * w[:, 2],
                         b[:, 5] * w[:, 2]], axis=1)

    def _b(self, u: np.ndarray) -> np.ndarray:
        """B u (rows)."""
        b = self.b
        return np.stack([b[:, 0] * u[:, 0],
                         b[:, 1] * u[:, 0] + b[:, 2] * u[:, 1],
                         b[:, 3] * u[:, 0] + b[:, 4] * u[:, 1] + b[:, 5] * u[:, 2]], axis=1)

    def _b_inv(self, m: np.ndarray) -> np.ndarray:
        """B⁻¹ m by forward substitution."""
        b = self.b
        y0 = m[:, 0] / b[:, 0]
        y1 = (m[:, 1] - b[:, 1] * y0) / b[:, 2]
        y2 = (m[:, 2] - b[:, 3] * y0 - b[:, 4] * y1) / b[:, 5]
        return np.stack([y0, y1, y2], axis=1)

    def sigma_scale(self, d):
        v = self._bt(d)
        return np.sqrt(dot(v, v))

    def distribution(self, m: np.ndarray) -> np.ndarray:
        """Heitz's D(m) (integrates to 4 over the sphere)."""
        y = self._b_inv(m)
        q = dot(y, y)  # mᵀ S⁻¹ m ≥ 1/λmax(S) > 0 for unit m
        det_sqrt = self.b[:, 0] * self.b[:, 2] * self.b[:, 5]
        return 1.0 / (np.pi * det_sqrt * q * q)

    def eval(self, d_in, d_out):
        h = d_out - d_in
        length = np.sqrt(dot(h, h))
        ok = length > 1e-12  # exact forward scattering: h undefined (measure zero)
        h = h / np.where(ok, length, 1.0)[:, None]
        sigma = self.sigma_scale(d_in)
        value = self.distribution(h) / (4.0 * np.maximum(sigma, 1e-300))
        return np.where(ok, value, 0.0)

    def connect(self, a, b, s_a=None, s_b=None):
        # h = a + b (unnormalised): D(ĥ) = |h|⁴ / (π √det S (hᵀ S⁻¹ h)²); p(−a → b) = D(ĥ)/(4 s(a)).
        s_a = self.sigma_scale(np.ascontiguousarray(a.T)) if s_a is None else s_a
        s_b = self.sigma_scale(np.ascontiguousarray(b.T)) if s_b is None else s_b
        h0, h1, h2 = a[0] + b[0], a[1] + b[1], a[2] + b[2]
        l2 = h0 * h0 + h1 * h1 + h2 * h2
        ok = l2 > 1e-24  # exact forward scattering: h undefined (measure zero)
        bb = self.b.T  # (6, 1|m)
        y0 = h0 / bb[0]
        y1 = (h1 - bb[1] * y0) / bb[2]
        y2 = (h2 - bb[3] * y0 - bb[4] * y1) / bb[5]
        q = y0 * y0 + y1 * y1 + y2 * y2
        det_sqrt = bb[0] * bb[2] * bb[5]
        d = np.where(ok, (l2 * l2) / np.where(ok, np.pi * det_sqrt * q * q, 1.0), 0.0) * 0.25
        return d / np.maximum(s_a, 1e-300), d / np.maximum(s_b, 1e-300)

    def sample(self, d_in, rng):
        n = d_in.shape[0]
        wi = -d_in
        axis = unit_or(self._bt(wi), [0.0, 0.0, 1.0])
        axis = np.broadcast_to(axis, (n, 3))
        u = rng.random((n, 2))
        # Cosine-weighted hemisphere about ``axis``: cos θ = √(1 − u0).
        cos_t = np.sqrt(1.0 - u[:, 0])
        sin_t = np.sqrt(u[:, 0])
        v = around(np.ascontiguousarray(axis), cos_t, sin_t, 2.0 * np.pi * u[:, 1])
        m = unit_or(self._b(v), [0.0, 0.0, 1.0])
        d_out = 2.0 * dot(wi, m)[:, None] * m - wi
        pdf = self.eval(d_in, d_out)
        self.stats.samples += n
        return PhaseSample(d_out, np.ones(n), pdf)

    def take(self, idx):
        other = SGGX.__new__(SGGX)
        other.s6 = lanes(self.s6, idx)
        other.b = lanes(self.b, idx)
        return self._child(other)
