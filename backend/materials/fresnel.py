"""Fresnel reflectance: exact, unpolarised, for dielectric and conductor interfaces.

Conventions
-----------
* ``cos_i`` is the cosine between the incident direction (pointing *away* from the surface) and
  the interface normal, signed: > 0 means the light/path arrives from the side the normal points
  to ("above"), < 0 from below.
* A dielectric interface is described by its relative index ``eta = n_below / n_above`` (any
  positive value; < 1 when the denser medium is above). Arriving from below, the relative index
  seen by the ray is 1/eta; the functions handle both sides, including total internal reflection.
* Conductors: complex index ``eta + i k`` per RGB channel, *relative* to the (lossless) dielectric
  the light arrives in (divide both by that medium's index). Only arrival from the dielectric side
  makes sense, so |cos_i| is used.

Precision: float64 throughout; every division is guarded (no NaN/Inf for cos_i = 0, eta = 1, TIR).
"""
from __future__ import annotations

import numpy as np


def _safe_div(num: np.ndarray, den: np.ndarray, fallback: float) -> np.ndarray:
    num, den = np.broadcast_arrays(num, den)
    return np.divide(num, den, out=np.full(num.shape, fallback), where=den > 0)


def dielectric_polarized(cos_i, eta):
    """Amplitude-squared reflectances (Rs, Rp) and the refraction geometry.

    Returns ``(Rs, Rp, cos_t, eta_ti)``: ``cos_t`` is the signed cosine of the refracted direction
    (opposite sign to ``cos_i``; 0 under total internal reflection) and ``eta_ti = n_t / n_i`` the
    relative index from the incident to the transmitted side. Rs = Rp = 1 under TIR.
    """
    cos_i = np.asarray(cos_i, dtype=np.float64)
    eta = np.asarray(eta, dtype=np.float64)
    above = cos_i >= 0
    eta_ti = np.where(above, eta, 1.0 / eta)
    ci = np.minimum(np.abs(cos_i), 1.0)
    # Snell: sin_t = sin_i / eta_ti. Written with 1 - cos² so that cos_i close to 1 stays exact.
    sin2_t = (1.0 - ci * ci) / (eta_ti * eta_ti)
    tir = sin2_t >= 1.0
    ct = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    # rs = (ci - η ct)/(ci + η ct), rp = (η ci - ct)/(η ci + ct) (Born & Wolf, Principles of
    # Optics, ch. 1). Both denominators vanish only when ci = ct = 0 (grazing at exactly eta = 1, or the TIR edge),
    # where the reflectance is 1 in the limit.
    rs = _safe_div(ci - eta_ti * ct, ci + eta_ti * ct, 1.0)
    rp = _safe_div(eta_ti * ci - ct, eta_ti * ci + ct, 1.0)
    Rs = np.where(tir, 1.0, rs * rs)
    Rp = np.where(tir, 1.0, rp * rp)
    cos_t = np.where(tir, 0.0, np.where(above, -ct, ct))
    return Rs, Rp, cos_t, eta_ti


def dielectric(cos_i, eta):
    """Unpolarised reflectance F = (Rs + Rp)/2 of a dielectric interface.

    Returns ``(F, cos_t, eta_ti)`` as :func:`dielectric_polarized` (F = 1 under TIR).
    """
    Rs, Rp, cos_t, eta_ti = dielectric_polarized(cos_i, eta)
    return 0.5 * (Rs + Rp), cos_t, eta_ti


def conductor_polarized(cos_i, eta, k):
    """(Rs, Rp) of a conductor with relative complex index eta + i k; broadcasts cos_i against
    eta/k (e.g. cos_i (n, 1) with eta (n, 3) or (1, 3)).

    Exact formula for an absorbing medium seen from a lossless one (Born & Wolf, Principles of
    Optics, optics of metals): with s² = sin²θ, a² + b² = |ñ² − s²| and
    a = Re sqrt(ñ² − s²),
        Rs = ((a − cosθ)² + b²) / ((a + cosθ)² + b²)
        Rp = Rs · ((a − s·tanθ)² + b²) / ((a + s·tanθ)² + b²)
    (the Rp factor is multiplied through by cos²θ below so that cosθ = 0 needs no tanθ).
    """
    c = np.minimum(np.abs(np.asarray(cos_i, dtype=np.float64)), 1.0)
    eta = np.asarray(eta, dtype=np.float64)
    k = np.asarray(k, dtype=np.float64)
    c2 = c * c
    s2 = 1.0 - c2
    t0 = eta * eta - k * k - s2
    a2b2 = np.sqrt(t0 * t0 + 4.0 * eta * eta * k * k)
    a = np.sqrt(np.maximum(0.0, 0.5 * (a2b2 + t0)))
    t1 = a2b2 + c2
    t2 = 2.0 * a * c
    Rs = _safe_div(t1 - t2, t1 + t2, 1.0)
    t3 = c2 * a2b2 + s2 * s2
    t4 = t2 * s2
    Rp = Rs * _safe_div(t3 - t4, t3 + t4, 1.0)
    return np.clip(Rs, 0.0, 1.0), np.clip(Rp, 0.0, 1.0)


def conductor(cos_i, eta, k):
    """Unpolarised reflectance (Rs + Rp)/2 of a conductor; see :func:`conductor_polarized`."""
    Rs, Rp = conductor_polarized(cos_i, eta, k)
    return 0.5 * (Rs + Rp)
