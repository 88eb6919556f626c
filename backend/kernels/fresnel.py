"""Exact unpolarised Fresnel reflectance of dielectric and conductor interfaces, per lane.

Conventions: ``cos_i`` is the signed cosine between the incident direction (pointing away from
the surface) and the interface normal; > 0 arrives from the side the normal points to ("above").
A dielectric interface has the relative index ``eta = n_below / n_above``; arriving from below
the ray sees 1/eta. Conductors: complex index eta + i k relative to the lossless dielectric the
light arrives in; |cos_i| is used. Every division is guarded (cos_i = 0, eta = 1, total
internal reflection give finite values). float64: 1 − cos² cancels in float32 near normal
incidence.
"""
from __future__ import annotations

import math

from .jit import kernel


@kernel
def dielectric_polarized(cos_i, eta):
    """(Rs, Rp, cos_t, eta_ti): amplitude-squared reflectances, the signed cosine of the refracted
    direction (opposite sign to cos_i; 0 under TIR) and eta_ti = n_t / n_i. Rs = Rp = 1 under TIR.
    rs = (ci − η ct)/(ci + η ct), rp = (η ci − ct)/(η ci + ct) (Born & Wolf, ch. 1)."""
    above = cos_i >= 0.0
    eta_ti = eta if above else 1.0 / eta
    ci = min(abs(cos_i), 1.0)
    sin2_t = (1.0 - ci * ci) / (eta_ti * eta_ti)
    if sin2_t >= 1.0:
        return 1.0, 1.0, 0.0, eta_ti
    ct = math.sqrt(max(0.0, 1.0 - sin2_t))
    ds = ci + eta_ti * ct
    dp = eta_ti * ci + ct
    # Both denominators vanish only when ci = ct = 0, where the reflectance is 1 in the limit.
    rs = (ci - eta_ti * ct) / ds if ds > 0.0 else 1.0
    rp = (eta_ti * ci - ct) / dp if dp > 0.0 else 1.0
    cos_t = -ct if above else ct
    return rs * rs, rp * rp, cos_t, eta_ti


@kernel
def dielectric(cos_i, eta):
    """(F, cos_t, eta_ti) with F = (Rs + Rp)/2 (1 under total internal reflection)."""
    Rs, Rp, cos_t, eta_ti = dielectric_polarized(cos_i, eta)
    return 0.5 * (Rs + Rp), cos_t, eta_ti


@kernel
def conductor_polarized(cos_i, eta, k):
    """(Rs, Rp) of a conductor, exact (Born & Wolf, optics of metals): with s² = sin²θ,
    a² + b² = |ñ² − s²|, a = Re √(ñ² − s²):
        Rs = ((a − cosθ)² + b²)/((a + cosθ)² + b²),
        Rp = Rs ((a − s tanθ)² + b²)/((a + s tanθ)² + b²)  (× cos²θ through, so cosθ = 0 is fine)."""
    c = min(abs(cos_i), 1.0)
    c2 = c * c
    s2 = 1.0 - c2
    t0 = eta * eta - k * k - s2
    a2b2 = math.sqrt(t0 * t0 + 4.0 * eta * eta * k * k)
    a = math.sqrt(max(0.0, 0.5 * (a2b2 + t0)))
    t1 = a2b2 + c2
    t2 = 2.0 * a * c
    Rs = (t1 - t2) / (t1 + t2) if t1 + t2 > 0.0 else 1.0
    t3 = c2 * a2b2 + s2 * s2
    t4 = t2 * s2
    Rp = Rs * ((t3 - t4) / (t3 + t4) if t3 + t4 > 0.0 else 1.0)
    return min(max(Rs, 0.0), 1.0), min(max(Rp, 0.0), 1.0)


@kernel
def conductor(cos_i, eta, k):
    Rs, Rp = conductor_polarized(cos_i, eta, k)
    return 0.5 * (Rs + Rp)


@kernel
def conductor_rgb(cos_i, eta, k):
    """Per RGB channel; eta and k are 3-tuples."""
    return (conductor(cos_i, eta[0], k[0]), conductor(cos_i, eta[1], k[1]),
            conductor(cos_i, eta[2], k[2]))
