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

from .base import Phase, lane_count, lanes, unit_or, vector_lanes

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
    """SGGX phase with matrix ``s6`` of shape (6,), (1, 6) or (n, 6) (see module docstring); the
    per-lane maths is compiled (backend/kernels/layered/phase.py)."""

    type_name = "sggx"
    directional = True

    def __init__(self, s6):
        super().__init__()
        s6 = np.asarray(s6, dtype=np.float64)
        self.s6 = s6.reshape(1, 6) if s6.size == 6 else s6.reshape(-1, 6)
        self.b = cholesky(self.s6)

    @classmethod
    def from_params(cls, settings: dict, orientation, roughness) -> "SGGX":
        return cls(preset_matrix(settings["shape"], orientation, roughness))

    @classmethod
    def fiber(cls, axis, roughness) -> "SGGX":
        return cls(preset_matrix("fiber", axis, roughness))

    @classmethod
    def flake(cls, normal, roughness) -> "SGGX":
        return cls(preset_matrix("flake", normal, roughness))

    @property
    def n(self):
        return lane_count(self.s6)

    def _bind_rows(self):
        from ...kernels.layered import phase as kp
        from ...kernels.layered.phase_batch import bind_sggx_rows
        P = np.zeros((self.s6.shape[0], kp.SIZE))
        bind_sggx_rows(np.ascontiguousarray(self.s6), P)
        return P

    def distribution(self, m: np.ndarray) -> np.ndarray:
        """Heitz's D(m) (integrates to 4 over the sphere)."""
        b = self.b
        y0 = m[:, 0] / b[:, 0]
        y1 = (m[:, 1] - b[:, 1] * y0) / b[:, 2]
        y2 = (m[:, 2] - b[:, 3] * y0 - b[:, 4] * y1) / b[:, 5]
        q = y0 * y0 + y1 * y1 + y2 * y2  # mᵀ S⁻¹ m ≥ 1/λmax(S) > 0 for unit m
        det_sqrt = b[:, 0] * b[:, 2] * b[:, 5]
        return 1.0 / (np.pi * det_sqrt * q * q)

    def take(self, idx):
        other = SGGX.__new__(SGGX)
        other.s6 = lanes(self.s6, idx)
        other.b = lanes(self.b, idx)
        return self._child(other)
