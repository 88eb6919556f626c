"""Anisotropic microfacet distributions (GGX, Beckmann): NDF, Smith masking, sampling.

Frame: local shading frame, z = macro normal, x = UV tangent. ``alpha_u`` is the roughness
along x, ``alpha_v`` along y (both the microfacet α, i.e. RMS-slope-like, not Blender's slider).
Parameters broadcast per lane: shape () for constants or (n,) for textured values.

Microfacet normals ``m`` always lie in the upper hemisphere (m.z > 0). Directions ``w`` may lie on
either side; the Smith Λ only depends on |w.z|, and the "visible side" indicator χ⁺ is
(w·m)·w.z > 0 (a facet seen from below is seen through its back side when the path is below).

Masking-shadowing (Heitz 2014, "Understanding the Masking-Shadowing Function"):
* ``height-correlated``: G2 = 1 / (1 + Λ(wi) + Λ(wo)) — the form Cycles uses, for reflection and
  (also as in Cycles) for transmission.
* ``separable``: G2 = G1(wi) G1(wo) — Mitsuba 0.6 and Guo et al.'s reference. As there, the
  Beckmann G1 is Walter et al. 2007's rational approximation (guo2018-digest §17); GGX's is exact.
Visible-normal pdfs always use the *exact* G1, because that is the density the samplers draw.

Sampling:
* ``sample_ndf``: m ∝ D(m) cosθm (slope-space inversion, scaled by αu/αv).
* ``sample_visible``: m ∝ G1(wi, m) max(0, wi·m) D(m) / cosθi. GGX: stretch to α = 1 and draw
  the visible hemisphere as a spherical cap (Heitz 2018 JCGT; cap form of Dupuy & Benyoub 2023).
  Beckmann: stretch, draw the visible slope along the incident plane by inverting its CDF
  (Heitz & d'Eon 2014 / Jakob 2014 approach; here a safeguarded Newton iteration), the orthogonal
  slope from its Gaussian, rotate and unstretch.

Robustness: α is clamped to ``ALPHA_MIN`` = 1e-4; cosines down to 1e-6 (and exactly 0) give finite
results. All maths float64.
"""
from __future__ import annotations

import numpy as np

from .specfun import SQRT_PI, erfc, erfinv_from_uniform

GGX = "ggx"
BECKMANN = "beckmann"
HEIGHT_CORRELATED = "height-correlated"
SEPARABLE = "separable"
DISTRIBUTIONS = (GGX, BECKMANN)
MASKINGS = (HEIGHT_CORRELATED, SEPARABLE)

ALPHA_MIN = 1e-4
_TINY = 1e-300
INV_PI = 1.0 / np.pi


def _div(num, den):
    """num/den where den > 0, else 0."""
    ok = den > 0
    return np.where(ok, num / np.where(ok, den, 1.0), 0.0)


def _normalize(v):
    n = np.sqrt(np.einsum("ij,ij->i", v, v))
    return v / np.where(n > 0, n, 1.0)[:, None]


class Microfacet:
    """A microfacet distribution bound to lanes (αu, αv of shape () or (n,))."""

    def __init__(self, distribution: str, alpha_u, alpha_v=None, masking: str = HEIGHT_CORRELATED):
        if distribution not in DISTRIBUTIONS:
            raise ValueError(f"unknown microfacet distribution {distribution!r}")
        if masking not in MASKINGS:
            raise ValueError(f"unknown masking {masking!r}")
        self.distribution = distribution
        self.masking = masking
        au = np.asarray(alpha_u, dtype=np.float64)
        av = au if alpha_v is None else np.asarray(alpha_v, dtype=np.float64)
        self.au = np.maximum(au, ALPHA_MIN)
        self.av = np.maximum(av, ALPHA_MIN)

    # ------------------------------------------------------------------ NDF
    def D(self, m: np.ndarray) -> np.ndarray:
        """Normal distribution D(m) (per steradian of m; ∫ D(m) cosθm dm = 1); 0 for m.z <= 0."""
        x, y, z = m[:, 0], m[:, 1], m[:, 2]
        au, av = self.au, self.av
        up = z > 0
        z2 = z * z
        if self.distribution == GGX:
            # 1 / (π αu αv (x²/αu² + y²/αv² + z²)²); the bracket is > 0 for unit m.
            k = x * x / (au * au) + y * y / (av * av) + z2
            d = _div(INV_PI / (au * av), k * k)
        else:
            # exp(-tan²θ (cos²φ/αu² + sin²φ/αv²)) / (π αu αv cos⁴θ); exp underflows to 0
            # before cos⁴θ does, so guarding the division is enough.
            e = _div(x * x / (au * au) + y * y / (av * av), z2)
            d = _div(np.exp(-e) * (INV_PI / (au * av)), z2 * z2)
            d = np.where(z2 > 0, d, 0.0)
        return np.where(up, d, 0.0)

    def _alpha2_tan2(self, w):
        """α(φ)² tan²θ of direction w (projected roughness times squared slope), >= 0, finite."""
        x, y, z = w[:, 0], w[:, 1], w[:, 2]
        num = self.au * self.au * x * x + self.av * self.av * y * y
        return num / np.maximum(z * z, _TINY)

    def smith_lambda(self, w: np.ndarray) -> np.ndarray:
        """Smith Λ(w) (exact for both distributions); depends on |w.z| only; finite for w.z = 0."""
        s = self._alpha2_tan2(w)
        if self.distribution == GGX:
            # (sqrt(1 + s) - 1)/2 written without cancellation for small s.
            return s / (2.0 * (1.0 + np.sqrt(1.0 + s)))
        # Beckmann: a = 1/(α tanθ), Λ = (erf(a) - 1)/2 + exp(-a²)/(2a√π). Λ < 1e-17 for a > 6.
        a = 1.0 / np.sqrt(np.maximum(s, 1e-200))
        a = np.maximum(a, 1e-150)
        small = a < 6.0
        a_s = np.where(small, a, 1.0)
        lam = 0.5 * (np.exp(-a_s * a_s) / (a_s * SQRT_PI) - erfc(a_s))
        return np.where(small, np.maximum(lam, 0.0), 0.0)

    def G1(self, w: np.ndarray, m: np.ndarray) -> np.ndarray:
        """Exact Smith masking G1(w, m) = χ⁺ / (1 + Λ(w))."""
        chi = (np.einsum("ij,ij->i", w, m) * w[:, 2]) > 0
        return np.where(chi, 1.0 / (1.0 + self.smith_lambda(w)), 0.0)

    def _G1_separable(self, w, m):
        if self.distribution == GGX:
            return self.G1(w, m)
        # Walter et al. 2007, eq. 27: rational fit of the Beckmann G1, exact to ~1e-3; 1 above 1.6.
        chi = (np.einsum("ij,ij->i", w, m) * w[:, 2]) > 0
        a = 1.0 / np.sqrt(np.maximum(self._alpha2_tan2(w), 1e-200))
        g = np.where(a < 1.6, (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a), 1.0)
        return np.where(chi, g, 0.0)

    def G(self, wi: np.ndarray, wo: np.ndarray, m: np.ndarray) -> np.ndarray:
        """Masking-shadowing G2(wi, wo, m) of the chosen form (reflection or transmission)."""
        if self.masking == SEPARABLE:
            return self._G1_separable(wi, m) * self._G1_separable(wo, m)
        chi = ((np.einsum("ij,ij->i", wi, m) * wi[:, 2]) > 0) & \
              ((np.einsum("ij,ij->i", wo, m) * wo[:, 2]) > 0)
        return np.where(chi, 1.0 / (1.0 + self.smith_lambda(wi) + self.smith_lambda(wo)), 0.0)

    # ------------------------------------------------------------------ sampling D(m) cosθm
    def _standard_slopes(self, u: np.ndarray):
        """Slopes of the α = 1 isotropic distribution, radius by CDF inversion, angle uniform."""
        u1 = np.minimum(u[:, 0], np.nextafter(1.0, 0.0))
        if self.distribution == GGX:
            r2 = u1 / (1.0 - u1)           # P(r²) ∝ 1/(1 + r²)²
        else:
            r2 = -np.log1p(-u1)            # P(r²) ∝ exp(-r²)
        r = np.sqrt(r2)
        phi = 2.0 * np.pi * u[:, 1]
        return r * np.cos(phi), r * np.sin(phi)

    def sample_ndf(self, u: np.ndarray) -> np.ndarray:
        """m with density D(m) cosθm (solid angle), from u (n, 2) in [0, 1)²."""
        sx, sy = self._standard_slopes(u)
        sx = sx * self.au
        sy = sy * self.av
        m = np.stack([-sx, -sy, np.ones_like(sx)], axis=1)
        return _normalize(m)

    def pdf_ndf(self, m: np.ndarray) -> np.ndarray:
        return self.D(m) * np.maximum(m[:, 2], 0.0)

    # ------------------------------------------------------------------ visible normals
    def sample_visible(self, wi: np.ndarray, u: np.ndarray) -> np.ndarray:
        """m ∝ G1(wi, m) max(0, wi·m) D(m) / wi.z for wi in the upper hemisphere (wi.z >= 0)."""
        n = wi.shape[0]
        au = np.broadcast_to(self.au, (n,))
        av = np.broadcast_to(self.av, (n,))
        # Stretch to the α = 1 configuration.
        ws = _normalize(np.stack([au * wi[:, 0], av * wi[:, 1], np.maximum(wi[:, 2], 0.0)], axis=1))
        if self.distribution == GGX:
            h = self._sample_ggx_visible_std(ws, u)
            m = np.stack([au * h[:, 0], av * h[:, 1], np.maximum(h[:, 2], 0.0)], axis=1)
        else:
            sx, sy = self._sample_beckmann_visible_slopes(ws, u)
            m = np.stack([-au * sx, -av * sy, np.ones(n)], axis=1)
        m = _normalize(m)
        # A horizontal normal (measure zero) would have D = 0; nudge it up so it stays a unit
        # vector in the upper hemisphere (its weight is 0 anyway).
        flat = m[:, 2] <= 0
        if flat.any():
            m[flat] = np.array([0.0, 0.0, 1.0])
        return m

    @staticmethod
    def _sample_ggx_visible_std(ws, u):
        # The visible normals of the α = 1 GGX (a hemisphere) seen from ws are ws + a uniform
        # point on the spherical cap z >= -ws.z of the unit sphere (Dupuy & Benyoub 2023).
        phi = 2.0 * np.pi * u[:, 0]
        z = (1.0 - u[:, 1]) * (1.0 + ws[:, 2]) - ws[:, 2]
        sin_t = np.sqrt(np.clip(1.0 - z * z, 0.0, 1.0))
        c = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), z], axis=1)
        return c + ws

    @staticmethod
    def _sample_beckmann_visible_slopes(ws, u):
        """Visible slopes of the α = 1 Beckmann distribution seen from ws, in the shading frame."""
        cos_t = np.clip(ws[:, 2], 0.0, 1.0)
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
        # μ = cot θ; slopes along the incident plane have density ∝ (μ − x) e^{−x²} for x < μ
        # (the projected-area factor), CDF C(x) = [μ erfc(−x) + e^{−x²}/√π] / 2.
        mu = cos_t / np.maximum(sin_t, 1e-300)
        hi = np.minimum(mu, 8.0)           # density beyond 8 is < e^-64 relative
        lo = np.full_like(hi, -8.0)

        u1 = np.clip(u[:, 0], 1e-16, 1.0 - 1e-16)
        target = u1 * 0.5 * (mu * erfc(-hi) + np.exp(-hi * hi) / SQRT_PI)
        x = np.where(hi > 0.0, 0.0, 0.5 * (lo + hi))
        # Newton with bisection fallback, iterating only on lanes not yet converged.
        act = np.arange(x.size)
        m_, t_, lo_, hi_, x_ = mu, target, lo, hi, x
        for _ in range(50):
            g = 0.5 * (m_ * erfc(-x_) + np.exp(-x_ * x_) / SQRT_PI) - t_
            above = g > 0
            hi_ = np.where(above, x_, hi_)
            lo_ = np.where(above, lo_, x_)
            dg = (m_ - x_) * np.exp(-x_ * x_) / SQRT_PI
            ok = dg > 0
            xn = x_ - g / np.where(ok, dg, 1.0)
            inside = ok & (xn >= lo_) & (xn <= hi_)   # x itself is a bracket end
            xn = np.where(inside, xn, 0.5 * (lo_ + hi_))
            # erfc is accurate to ~1e-7 relative, so x cannot be resolved much below that.
            done = np.abs(xn - x_) <= 1e-10 * (1.0 + np.abs(x_))
            x[act] = xn
            keep = ~done
            if not keep.any():
                break
            act = act[keep]
            m_, t_, lo_, hi_, x_ = m_[keep], t_[keep], lo_[keep], hi_[keep], xn[keep]
        y = erfinv_from_uniform(u[:, 1])  # orthogonal slope: N(0, 1/2), independent
        # Rotate from the incident plane to the shading frame.
        r = np.hypot(ws[:, 0], ws[:, 1])
        cphi = np.where(r > 0, ws[:, 0] / np.where(r > 0, r, 1.0), 1.0)
        sphi = np.where(r > 0, ws[:, 1] / np.where(r > 0, r, 1.0), 0.0)
        return cphi * x - sphi * y, sphi * x + cphi * y

    def pdf_visible(self, wi: np.ndarray, m: np.ndarray) -> np.ndarray:
        """Density of :meth:`sample_visible` (per steradian of m); wi in the upper hemisphere."""
        cos_wm = np.einsum("ij,ij->i", wi, m)
        return _div(self.G1(wi, m) * np.maximum(cos_wm, 0.0) * self.D(m), wi[:, 2])
