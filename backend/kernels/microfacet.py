"""Anisotropic microfacet distributions (GGX, Beckmann) per lane: NDF, Smith masking, sampling.

Frame: local shading frame, z = macro normal, x = UV tangent; ``au`` is the roughness α along x,
``av`` along y (the microfacet α, not Blender's slider). Callers clamp α to ``ALPHA_MIN`` = 1e-4.
Microfacet normals m lie in the upper hemisphere (m.z > 0). Directions w may lie on either side:
Λ depends on |w.z| only, and the visible-side indicator χ⁺ is (w·m)·w.z > 0.

Masking-shadowing (Heitz 2014, "Understanding the Masking-Shadowing Function"):
* ``HEIGHT_CORRELATED``: G2 = 1/(1 + Λ(wi) + Λ(wo)), as Cycles, for reflection and transmission.
* ``SEPARABLE``: G2 = G1(wi) G1(wo), Mitsuba 0.6 and Guo et al.'s reference; as there the
  Beckmann G1 is Walter et al. 2007's rational approximation. Visible-normal
  densities always use the exact G1: it is the density the samplers draw.

Sampling: ``sample_ndf`` draws m ∝ D(m) cos θm (slope-space inversion scaled by αu, αv);
``sample_visible`` draws m ∝ G1(wi, m) max(0, wi·m) D(m)/cos θi. GGX: stretch to α = 1, visible
hemisphere as a spherical cap (Heitz 2018; cap form of Dupuy & Benyoub 2023). Beckmann: stretch,
invert the CDF of the visible slope along the incident plane (safeguarded Newton), draw the
orthogonal slope from its Gaussian, rotate and unstretch. Cosines down to 1e-6 (and 0) give
finite results. float64 (microfacet terms at α = 1e-4 lose all precision in float32).
"""
from __future__ import annotations

import math

from .jit import inlined, kernel
from .specfun import SQRT_PI, erfc, erfinv_from_uniform
from .turns import cos_sin_turns

from .microfacet_codes import (ALPHA_MIN, BECKMANN, DISTRIBUTION_CODES, GGX,  # noqa: F401 (re-exported)
                               HEIGHT_CORRELATED, MASKING_CODES, SEPARABLE)

_TINY = 1e-300
from .consts import INV_PI


@kernel
def D(dist, au, av, m):
    """Normal distribution (per steradian of m; ∫ D cos θm dm = 1); 0 for m.z ≤ 0."""
    x, y, z = m
    if z <= 0.0:
        return 0.0
    z2 = z * z
    q = x * x / (au * au) + y * y / (av * av)
    if dist == GGX:
        k = q + z2
        return (INV_PI / (au * av)) / (k * k) if k > 0.0 else 0.0
    # exp(−tan²θ(cos²φ/αu² + sin²φ/αv²)) / (π αu αv cos⁴θ); exp underflows before cos⁴θ does.
    if z2 <= 0.0:
        return 0.0
    d = math.exp(-q / z2) * (INV_PI / (au * av))
    zz = z2 * z2
    return d / zz if zz > 0.0 else 0.0


@inlined
def _tan2_terms(au, av, w):
    """(α(φ)² sin²θ, cos²θ clamped away from 0) of direction w: ``alpha2_tan2`` is their ratio."""
    return au * au * w[0] * w[0] + av * av * w[1] * w[1], max(w[2] * w[2], _TINY)


@kernel
def alpha2_tan2(au, av, w):
    """α(φ)² tan²θ of direction w (≥ 0, finite for w.z = 0)."""
    num, den = _tan2_terms(au, av, w)
    return num / den


@kernel
def smith_lambda(dist, au, av, w):
    """Smith Λ(w), exact for both distributions."""
    num, den = _tan2_terms(au, av, w)
    if dist == GGX:
        # (√(1 + s) − 1)/2 without cancellation for small s
        s = num / den
        return s / (2.0 * (1.0 + math.sqrt(1.0 + s)))
    # Beckmann: a = 1/(α tan θ), Λ = (erf(a) − 1)/2 + e^{−a²}/(2a√π); Λ < 1e-17 for a ≥ 6,
    # tested as 36·α²tan²θ ≤ 1 before the division and square root: most calls on a smooth coat
    # end here (Smith Λ was 7 % of the approximate pdf of the two-microflake-slab stack, perf).
    if 36.0 * num <= den:
        return 0.0
    a = max(1.0 / math.sqrt(max(num / den, 1e-200)), 1e-150)
    lam = 0.5 * (math.exp(-a * a) / (a * SQRT_PI) - erfc(a))
    return max(lam, 0.0)


@kernel
def visible_side(w, m):
    return (w[0] * m[0] + w[1] * m[1] + w[2] * m[2]) * w[2] > 0.0


@kernel
def G1(dist, au, av, w, m):
    """Exact Smith masking χ⁺/(1 + Λ(w))."""
    if not visible_side(w, m):
        return 0.0
    return 1.0 / (1.0 + smith_lambda(dist, au, av, w))


@kernel
def G1_separable(dist, au, av, w, m):
    if dist == GGX:
        return G1(dist, au, av, w, m)
    if not visible_side(w, m):
        return 0.0
    # Walter et al. 2007, eq. 27: rational fit of the Beckmann G1; 1 above a = 1.6.
    a = 1.0 / math.sqrt(max(alpha2_tan2(au, av, w), 1e-200))
    if a < 1.6:
        return (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
    return 1.0


@kernel
def G(dist, masking, au, av, wi, wo, m):
    """Masking-shadowing G2(wi, wo, m) of the chosen form (reflection or transmission)."""
    if masking == SEPARABLE:
        return G1_separable(dist, au, av, wi, m) * G1_separable(dist, au, av, wo, m)
    if not (visible_side(wi, m) and visible_side(wo, m)):
        return 0.0
    return 1.0 / (1.0 + smith_lambda(dist, au, av, wi) + smith_lambda(dist, au, av, wo))


@kernel
def _normalize(x, y, z):
    n = math.sqrt(x * x + y * y + z * z)
    if n > 0.0:
        return (x / n, y / n, z / n)
    return (x, y, z)


@kernel
def sample_ndf(dist, au, av, u0, u1):
    """m with density D(m) cos θm (solid angle)."""
    u0 = min(u0, 1.0 - 2.0 ** -53)
    if dist == GGX:
        r2 = u0 / (1.0 - u0)            # P(r²) ∝ 1/(1 + r²)²
    else:
        r2 = -math.log1p(-u0)           # P(r²) ∝ exp(−r²)
    r = math.sqrt(r2)
    c, s = cos_sin_turns(u1)
    return _normalize(-r * c * au, -r * s * av, 1.0)


@kernel
def pdf_ndf(dist, au, av, m):
    return D(dist, au, av, m) * max(m[2], 0.0)


@kernel
def _beckmann_visible_slopes(ws, u0, u1):
    """Visible slopes of the α = 1 Beckmann distribution seen from unit ws (shading frame)."""
    cos_t = min(max(ws[2], 0.0), 1.0)
    sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    # μ = cot θ; slopes along the incident plane have density ∝ (μ − x) e^{−x²} for x < μ, with
    # CDF C(x) = [μ erfc(−x) + e^{−x²}/√π]/2.
    mu = cos_t / max(sin_t, 1e-300)
    hi = min(mu, 8.0)              # density beyond 8 is < e^-64 relative
    lo = -8.0
    uu = min(max(u0, 1e-16), 1.0 - 1e-16)
    target = uu * 0.5 * (mu * erfc(-hi) + math.exp(-hi * hi) / SQRT_PI)
    x = 0.0 if hi > 0.0 else 0.5 * (lo + hi)
    for _ in range(50):
        g = 0.5 * (mu * erfc(-x) + math.exp(-x * x) / SQRT_PI) - target
        if g > 0.0:
            hi = x
        else:
            lo = x
        dg = (mu - x) * math.exp(-x * x) / SQRT_PI
        xn = 0.5 * (lo + hi)
        if dg > 0.0:
            xt = x - g / dg
            if lo <= xt <= hi:
                xn = xt
        # erfc is accurate to ~1e-7 relative: x cannot be resolved much below that.
        done = abs(xn - x) <= 1e-10 * (1.0 + abs(x))
        x = xn
        if done:
            break
    y = erfinv_from_uniform(u1)         # orthogonal slope: N(0, 1/2), independent
    r = math.hypot(ws[0], ws[1])
    if r > 0.0:
        cphi = ws[0] / r
        sphi = ws[1] / r
    else:
        cphi = 1.0
        sphi = 0.0
    return cphi * x - sphi * y, sphi * x + cphi * y


@kernel
def sample_visible(dist, au, av, wi, u0, u1):
    """m ∝ G1(wi, m) max(0, wi·m) D(m)/wi.z for wi in the upper hemisphere (wi.z ≥ 0)."""
    ws = _normalize(au * wi[0], av * wi[1], max(wi[2], 0.0))
    if dist == GGX:
        # Visible normals of the α = 1 GGX (a hemisphere) seen from ws: ws + a uniform point on
        # the spherical cap z ≥ −ws.z of the unit sphere.
        cp, sp = cos_sin_turns(u0)
        z = (1.0 - u1) * (1.0 + ws[2]) - ws[2]
        sin_t = math.sqrt(min(max(1.0 - z * z, 0.0), 1.0))
        hx = sin_t * cp + ws[0]
        hy = sin_t * sp + ws[1]
        hz = z + ws[2]
        m = _normalize(au * hx, av * hy, max(hz, 0.0))
    else:
        sx, sy = _beckmann_visible_slopes(ws, u0, u1)
        m = _normalize(-au * sx, -av * sy, 1.0)
    if m[2] <= 0.0:
        # A horizontal normal (measure zero) has D = 0: keep a unit vector in the upper
        # hemisphere (its weight is 0 anyway).
        return (0.0, 0.0, 1.0)
    return m


@kernel
def pdf_visible(dist, au, av, wi, m):
    """Density of ``sample_visible`` per steradian of m; wi in the upper hemisphere."""
    if wi[2] <= 0.0:
        return 0.0
    cos_wm = wi[0] * m[0] + wi[1] * m[1] + wi[2] * m[2]
    return G1(dist, au, av, wi, m) * max(cos_wm, 0.0) * D(dist, au, av, m) / wi[2]
