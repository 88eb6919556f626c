"""Fused interface kernels for the layered walk, structure-of-arrays.

The walk and the estimators need, for every interface vertex, the sample together with the
forward and reverse densities, and for every connection the value together with both densities.
The standard BSDFs (backend/materials) answer these as three separate calls on (n, 3) arrays;
these kernels compute them in one pass, sharing the half vector, D, Λ and Fresnel terms, on
(3, m) arrays (one contiguous row per component — several times faster in NumPy than (m, 3)
columns). The parameters and the maths are those of the bound ``materials`` BSDFs (tested equal
in tests/test_layered_kernels.py); interfaces of any other type (a nested layered BSDF, future
materials) go through :class:`GenericKernel`, which calls the standard BSDF interface.

Conventions: directions point away from the surface; ``eval(wi, wo)`` is IMPORTANCE transport
(the physical flow wi → wo) times |cos θo|; densities are per unit solid angle; delta samples
carry the placeholder densities 1 (see connect.py).

One deliberate difference: a Beckmann interface is sampled in the walk with m ∝ D(m) cos θm
(closed form) instead of visible normals (a Newton iteration on erfc, ~10× the cost); the
densities reported are those of this sampler, so the walk stays exact. GGX uses visible normals.
"""
from __future__ import annotations

import numpy as np

from ..materials.base import IMPORTANCE, lanes
from ..materials.conductor import ConductorBSDF
from ..materials.dielectric import DielectricBSDF
from ..materials.diffuse import DiffuseBSDF
from ..materials.fresnel import conductor as fresnel_conductor
from ..materials.fresnel import dielectric as fresnel_dielectric
from ..materials.microfacet import ALPHA_MIN, BECKMANN, GGX, SEPARABLE
from ..materials.specfun import _NR, SQRT_PI

INV_PI = 1.0 / np.pi
TINY = 1e-300


def sdiv(a, b):
    ok = b > 0
    return np.where(ok, a / np.where(ok, b, 1.0), 0.0)


def normalize3(v):
    n = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return v / np.where(n > 0, n, 1.0)


def dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def fresnel_F(c, eta):
    """Unpolarised dielectric reflectance for the signed cosine c (materials/fresnel.py, the
    same formula without its refraction outputs); 1 under total internal reflection."""
    eta_ti = np.where(c >= 0, eta, 1.0 / eta)
    ci = np.minimum(np.abs(c), 1.0)
    sin2_t = (1.0 - ci * ci) / (eta_ti * eta_ti)
    ct = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    a, b = eta_ti * ct, eta_ti * ci
    ds, dp = ci + a, b + ct
    # Both denominators vanish only when ci = ct = 0, where the reflectance is 1 in the limit.
    ok = (ds > 0) & (dp > 0)
    ds, dp = np.where(ok, ds, 1.0), np.where(ok, dp, 1.0)
    rs, rp = (ci - a) / ds, (b - ct) / dp
    return np.where((sin2_t < 1.0) & ok, 0.5 * (rs * rs + rp * rp), 1.0)


def rgb_rows(v) -> np.ndarray:
    """(1, 3) / (n, 3) RGB parameter → (3, 1) / (3, n)."""
    return np.ascontiguousarray(np.asarray(v, dtype=np.float64).reshape(-1, 3).T)


def lanes_rows(v, idx):
    """Subset a (3, 1|n) row parameter."""
    return v if v.shape[1] == 1 else v[:, idx]


class Microfacet3:
    """GGX / Beckmann NDF, Smith Λ and sampling on (3, m) vectors (see materials/microfacet.py).

    Masking is split into a per-direction term (``terms``: Λ, or the rational G1 for separable
    Beckmann) and its combination (``g2``), so that callers evaluating many direction pairs
    (the layered connections) compute each direction's term once."""

    def __init__(self, distribution, masking, au, av):
        self.ggx = distribution == GGX
        self.separable = masking == SEPARABLE
        self.au = np.maximum(np.asarray(au, dtype=np.float64), ALPHA_MIN)
        self.av = np.maximum(np.asarray(av, dtype=np.float64), ALPHA_MIN)
        self._iau2 = 1.0 / (self.au * self.au)
        self._iav2 = 1.0 / (self.av * self.av)
        self._norm = INV_PI / (self.au * self.av)

    @property
    def constant(self) -> bool:
        return self.au.ndim == 0 and self.av.ndim == 0

    def take(self, idx):
        if self.constant:
            return self
        return Microfacet3(GGX if self.ggx else BECKMANN, SEPARABLE if self.separable else "",
                           lanes(self.au, idx), lanes(self.av, idx))

    def D(self, m):
        x, y, z = m
        z2 = z * z
        q = x * x * self._iau2 + y * y * self._iav2
        ok = z > 0
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            if self.ggx:
                k = q + z2
                d = self._norm / (k * k)
            else:
                d = np.exp(-q / z2) * self._norm / (z2 * z2)
        return np.where(ok, d, 0.0)

    def _s(self, w):
        x, y, z = w
        return (self.au * self.au * x * x + self.av * self.av * y * y) / np.maximum(z * z, 1e-300)

    def lam(self, w):
        """Exact Smith Λ(w)."""
        s = self._s(w)
        if self.ggx:
            return s / (2.0 * (1.0 + np.sqrt(1.0 + s)))
        # Beckmann: Λ = (e^{−a²}/(a√π) − erfc(a))/2 with a = 1/√s, 0 for a ≥ 6 (below 1e-17).
        # erfc(a) for a > 0 is t·e^{−a² + P(t)} (specfun.erfc, Numerical Recipes' erfcc), so
        # e^{−a²} factors out of both terms: one exp fewer, no sign branch.
        r = np.sqrt(np.maximum(s, 1e-200))     # 1/a
        small = r > 1.0 / 6.0
        a = 1.0 / np.where(small, r, 1.0)
        t = 1.0 / (1.0 + 0.5 * a)
        poly = _NR[-1]
        for c in _NR[-2::-1]:
            poly = c + t * poly
        v = (0.5 * np.exp(-a * a)) * (r * (1.0 / SQRT_PI) - t * np.exp(poly))
        return np.where(small, np.maximum(v, 0.0), 0.0)

    def g1_separable(self, w):
        """Mitsuba/Walter rational Beckmann G1 (without the side test); GGX exact."""
        if self.ggx:
            return 1.0 / (1.0 + self.lam(w))
        a = 1.0 / np.sqrt(np.maximum(self._s(w), 1e-200))
        return np.where(a < 1.6, (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a), 1.0)

    @property
    def _rational(self) -> bool:
        return self.separable and not self.ggx

    def terms(self, w):
        """The per-direction masking term: the rational G1 for separable Beckmann, else Λ."""
        return self.g1_separable(w) if self._rational else self.lam(w)

    def g2(self, ti, to, chi):
        """G2 from two directions' ``terms``, 0 where ``chi`` (the visible-side tests) fails."""
        if self._rational:
            g = ti * to
        elif self.separable:
            g = 1.0 / ((1.0 + ti) * (1.0 + to))
        else:
            g = 1.0 / (1.0 + ti + to)
        return np.where(chi, g, 0.0)

    def g1(self, t):
        """1/(1 + Λ) from a (non-rational) term; used by the GGX visible-normal densities."""
        return 1.0 / (1.0 + t)

    def masking(self, wi, wo, chi_i, chi_o):
        """(G2(wi, wo), 1/(1 + Λ(wi)), 1/(1 + Λ(wo))) with the visible-side indicators."""
        li, lo = self.lam(wi), self.lam(wo)
        g1i = 1.0 / (1.0 + li)
        g1o = 1.0 / (1.0 + lo)
        if self.separable:
            g2 = (self.g1_separable(wi) * self.g1_separable(wo)) if not self.ggx else g1i * g1o
        else:
            g2 = 1.0 / (1.0 + li + lo)
        return np.where(chi_i & chi_o, g2, 0.0), np.where(chi_i, g1i, 0.0), np.where(chi_o, g1o, 0.0)

    def sample(self, ws, u0, u1):
        """A microfacet normal for the upper-hemisphere direction ws; see ``density``."""
        m = ws.shape[1]
        if self.ggx:
            au = np.broadcast_to(self.au, (m,))
            av = np.broadcast_to(self.av, (m,))
            st = normalize3(np.stack([au * ws[0], av * ws[1], np.maximum(ws[2], 0.0)]))
            phi = 2.0 * np.pi * u0
            z = (1.0 - u1) * (1.0 + st[2]) - st[2]
            sin_t = np.sqrt(np.clip(1.0 - z * z, 0.0, 1.0))
            h = np.stack([sin_t * np.cos(phi) + st[0], sin_t * np.sin(phi) + st[1], z + st[2]])
            mm = normalize3(np.stack([au * h[0], av * h[1], np.maximum(h[2], 0.0)]))
        else:
            # m ∝ (−αu r cos φ, −αv r sin φ, 1) with r = tan θm/α: always in the upper hemisphere.
            r = np.sqrt(-np.log1p(-np.minimum(u0, np.nextafter(1.0, 0.0))))
            phi = 2.0 * np.pi * u1
            x = (-r * self.au) * np.cos(phi)
            y = (-r * self.av) * np.sin(phi)
            inv = 1.0 / np.sqrt(1.0 + x * x + y * y)
            return np.stack([x * inv, y * inv, inv])
        flat = mm[2] <= 0
        if flat.any():
            mm[:, flat] = np.array([[0.0], [0.0], [1.0]])
        return mm


class Kernel:
    delta_only = False
    transmissive = False
    generic = False
    framed = False     # has a shading normal (FramedKernel): walks apply ``arrival`` factors
    constant = False   # no per-lane parameter: ``take`` returns the kernel itself

    def arrival(self, w):
        return 1.0

    def mask_terms(self, w):
        """Per-direction masking terms for ``eval(..., ti=, to=)`` (None: nothing to share)."""
        return None


class NullKernel(Kernel):
    """Index-matched pass-through (optionally tinted): a delta transmission wo = −wi."""

    delta_only = True
    transmissive = True

    def __init__(self, tint=None):
        self.tint = tint  # (3, 1|n) or None
        self.constant = tint is None or tint.shape[1] == 1

    def take(self, idx):
        if self.tint is None or self.tint.shape[1] == 1:
            return self
        return NullKernel(self.tint[:, idx])

    def sample(self, wi, rng, need_rev=True, pdf_only=False):
        m = wi.shape[1]
        ok = (wi[2] != 0) * 1.0
        w = np.broadcast_to(ok, (3, m)) if self.tint is None else ok * self.tint
        return -wi, w, np.ones(m), np.ones(m), np.ones(m, bool)

    def eval(self, wi, wo, rng, need_rev=True, pdf_only=False):
        m = wi.shape[1]
        return np.zeros((3, m)), np.zeros(m), np.zeros(m)


class DiffuseKernel(Kernel):
    def __init__(self, color_rows):
        self.color = color_rows  # (3, 1|n)
        self.constant = color_rows.shape[1] == 1

    @classmethod
    def of(cls, bsdf: DiffuseBSDF):
        return cls(rgb_rows(bsdf.color))

    def take(self, idx):
        return self if self.color.shape[1] == 1 else DiffuseKernel(self.color[:, idx])

    def sample(self, wi, rng, need_rev=True, pdf_only=False):
        m = wi.shape[1]
        u = rng.random((2, m))
        r = np.sqrt(u[0])
        phi = 2.0 * np.pi * u[1]
        z = np.sqrt(np.maximum(0.0, 1.0 - u[0]))
        side = np.where(wi[2] < 0, -1.0, 1.0)
        wo = np.stack([r * np.cos(phi), r * np.sin(phi), z * side])
        ok = (wi[2] != 0) & (z > 0)
        weight = np.where(ok, self.color, 0.0)
        return wo, weight, np.where(ok, z * INV_PI, 0.0), np.abs(wi[2]) * INV_PI, np.zeros(m, bool)

    def eval(self, wi, wo, rng, need_rev=True, pdf_only=False):
        same = wi[2] * wo[2] > 0
        co = np.where(same, np.abs(wo[2]), 0.0)
        ci = np.where(same, np.abs(wi[2]), 0.0)
        return self.color * (co * INV_PI), co * INV_PI, ci * INV_PI


class ConductorKernel(Kernel):
    def __init__(self, eta, k, tint, mf: Microfacet3 | None, smooth):
        self.eta, self.k, self.tint = eta, k, tint  # (3, 1|n)
        self.mf = mf
        self.smooth = smooth                          # () or (n,) bool
        self.delta_only = bool(np.all(smooth))
        self.constant = (eta.shape[1] == 1 and k.shape[1] == 1 and tint.shape[1] == 1 and
                         np.ndim(smooth) == 0 and (mf is None or mf.constant))

    @classmethod
    def of(cls, b: ConductorBSDF):
        mf = None if b.delta_only else Microfacet3(b.distribution, b.masking, b.alpha_u, b.alpha_v)
        return cls(rgb_rows(b.eta), rgb_rows(b.k), rgb_rows(b.tint), mf, np.asarray(b.smooth))

    def take(self, idx):
        if self.constant:
            return self
        return ConductorKernel(lanes_rows(self.eta, idx), lanes_rows(self.k, idx),
                               lanes_rows(self.tint, idx), None if self.mf is None else self.mf.take(idx),
                               lanes(self.smooth, idx))

    def _fresnel(self, c):
        return fresnel_conductor(c[None, :], self.eta, self.k) * self.tint

    def mask_terms(self, w):
        return None if self.mf is None else self.mf.terms(w)

    def eval(self, wi, wo, rng, need_rev=True, pdf_only=False, ti=None, to=None):
        """``ti``/``to``: ``mask_terms`` of wi and wo if the caller has them."""
        m = wi.shape[1]
        if self.delta_only:
            return np.zeros((3, m)), np.zeros(m), np.zeros(m)
        # Two-sided: a query from below is mirrored into the upper hemisphere.
        s = np.where(wi[2] < 0, -1.0, 1.0)
        ci, co = wi[2] * s, wo[2] * s
        ok = (ci > 0) & (co > 0) & ~self.smooth
        hx, hy, hz = wi[0] + wo[0], wi[1] + wo[1], ci + co
        l2 = hx * hx + hy * hy + hz * hz
        inv = 1.0 / np.sqrt(np.where(l2 > 0, l2, 1.0))
        h = (hx * inv, hy * inv, hz * inv)
        cih = wi[0] * h[0] + wi[1] * h[1] + ci * h[2]
        mf = self.mf
        D = mf.D(h)
        chi = cih > 0
        if ti is None:
            ti = mf.terms(wi)
        if to is None:
            to = mf.terms(wo)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv4ci = 0.25 / ci
            value = None
            if not pdf_only:
                value = self._fresnel(cih) * np.where(ok, D * mf.g2(ti, to, chi) * inv4ci, 0.0)
            if mf.ggx:
                pf = np.where(ok & chi, mf.g1(ti) * D * inv4ci, 0.0)
                pr = np.where(ok & chi, mf.g1(to) * D * (0.25 / co), 0.0)
            else:
                pf = pr = np.where(ok & chi, D * h[2] * (0.25 / cih), 0.0)
        return value, pf, pr

    def sample(self, wi, rng, need_rev=True, pdf_only=False):
        """Sample a microfacet normal and reflect. The weight is formed directly (the D terms
        of value and density cancel); the densities, for the walks' MIS records, only when
        ``need_rev`` (they equal ``eval``'s at the sampled pair)."""
        m = wi.shape[1]
        s = np.where(wi[2] < 0, -1.0, 1.0)
        ci = wi[2] * s
        front = ci > 0
        if not self.delta_only:
            mf = self.mf
            u = rng.random((2, m))
            wis = np.stack([wi[0], wi[1], ci])
            mm = mf.sample(wis, u[0], u[1])
            c = wi[0] * mm[0] + wi[1] * mm[1] + ci * mm[2]
            c2 = 2.0 * c
            wo = np.stack([c2 * mm[0] - wi[0], c2 * mm[1] - wi[1], (c2 * mm[2] - ci) * s])
            co = wo[2] * s
            ok = front & (c > 0) & (co > 0) & ~self.smooth
            ti, to = mf.terms(wis), mf.terms(np.stack([wo[0], wo[1], co]))
            g2 = mf.g2(ti, to, ok)
            with np.errstate(divide="ignore", invalid="ignore"):
                if mf.ggx:
                    w1 = g2 * (1.0 + ti)                       # G2/G1(wi)
                else:
                    w1 = g2 * c / (ci * mm[2])                 # G2·(wi·m)/(cos θi cos θm)
                w1 = np.where(ok, w1, 0.0)
                if need_rev or pdf_only:
                    D = mf.D(mm)
                    if mf.ggx:
                        pf = np.where(ok, D * (0.25 / ci) / (1.0 + ti), 0.0)
                        pr = np.where(ok, D * (0.25 / co) / (1.0 + to), 0.0)
                    else:
                        pf = pr = np.where(ok, D * mm[2] * (0.25 / c), 0.0)
                    w1 = np.where(pf > 0, w1, 0.0)   # a density that underflowed: a failed sample
                else:
                    pf = pr = ok * 1.0
                weight = (pf > 0) * 1.0 if pdf_only else self._fresnel(c) * w1
            delta = np.zeros(m, bool)
        else:
            wo = np.zeros((3, m))
            weight = np.zeros((3, m))
            pf = pr = np.zeros(m)
            delta = np.zeros(m, bool)
        if np.any(self.smooth):
            sm = np.broadcast_to(self.smooth, (m,)) & front
            mirror = np.stack([-wi[0], -wi[1], wi[2]])
            wo = np.where(sm, mirror, wo)
            weight = np.where(sm, self._fresnel(ci), weight)
            pf = np.where(sm, 1.0, pf)
            pr = np.where(sm, 1.0, pr)
            delta = sm
        return wo, weight, pf, pr, delta


class DielectricKernel(Kernel):
    transmissive = True

    def __init__(self, eta, tint, mf: Microfacet3 | None, smooth):
        self.eta = np.asarray(eta, dtype=np.float64)  # n_below / n_above, () or (n,)
        self.tint = tint                               # (3, 1|n)
        self.mf = mf
        self.smooth = smooth
        self.delta_only = bool(np.all(smooth))
        self.constant = (self.eta.ndim == 0 and tint.shape[1] == 1 and np.ndim(smooth) == 0 and
                         (mf is None or mf.constant))

    @classmethod
    def of(cls, b: DielectricBSDF):
        mf = None if b.delta_only else Microfacet3(b.distribution, b.masking, b.alpha_u, b.alpha_v)
        return cls(b.eta, rgb_rows(b.tint), mf, np.asarray(b.smooth))

    def take(self, idx):
        if self.constant:
            return self
        return DielectricKernel(lanes(self.eta, idx), lanes_rows(self.tint, idx),
                                None if self.mf is None else self.mf.take(idx), lanes(self.smooth, idx))

    def mask_terms(self, w):
        return None if self.mf is None else self.mf.terms(w)

    def eval(self, wi, wo, rng, need_rev=True, pdf_only=False, ti=None, to=None):
        """Walter et al. 2007 rough dielectric (importance transport), with the densities of the
        sampler from each side. ``ti``/``to``: ``mask_terms`` of wi and wo if known.

        With e = n(wo side)/n(wi side), h ∝ wi + e'·wo (e' = 1 for a reflection) and
        den = wi·h + e·wo·h, the reflection and transmission lobes share one form:
            value = F'·D·G2/|cos i| · j_v,   pf = F'·p_h(wi)·j_f,   pr = F'·p_h(wo)·j_r,
        with F' = F or 1 − F and the Jacobians j_v = 1/4 | |wi·h|·e²|wo·h|/den²,
        j_f = 1/(4|wo·h|) | e²|wo·h|/den², j_r = 1/(4|wi·h|) | |wi·h|/den² (reflection |
        transmission; for the reverse density e²/den² of the other side equals 1/den²)."""
        m = wi.shape[1]
        if self.delta_only:
            return np.zeros((3, m)), np.zeros(m), np.zeros(m)
        mf = self.mf
        eta = self.eta
        ci, co = wi[2], wo[2]
        cc = ci * co
        refl = cc > 0
        e = np.where(ci > 0, eta, 1.0 / eta)          # n(wo side)/n(wi side) for transmission
        ew = np.where(refl, 1.0, e)
        hx, hy, hz = wi[0] + ew * wo[0], wi[1] + ew * wo[1], ci + ew * co
        l2 = hx * hx + hy * hy + hz * hz
        inv = np.where(hz < 0, -1.0, 1.0) / np.sqrt(np.where(l2 > 0, l2, 1.0))
        h = (hx * inv, hy * inv, hz * inv)
        okh = h[2] > 0
        cih = wi[0] * h[0] + wi[1] * h[1] + ci * h[2]
        coh = wo[0] * h[0] + wo[1] * h[1] + co * h[2]
        F = fresnel_F(cih, eta)
        ch = cih * coh
        r_ok = refl & (ch > 0)
        t_ok = (cc < 0) & (ch < 0)
        valid = (r_ok | t_ok) & okh & ~self.smooth
        D = mf.D(h)
        chi_i, chi_o = cih * ci > 0, coh * co > 0
        acih, acoh = np.abs(cih), np.abs(coh)
        den = cih + e * coh
        Fs = np.where(r_ok, F, 1.0 - F)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            inv_d2 = 1.0 / (den * den)
            e2 = e * e
            if pdf_only:
                value = None
            else:
                if ti is None:
                    ti = mf.terms(wi)
                if to is None:
                    to = mf.terms(wo)
                jv = np.where(r_ok, 0.25, acih * e2 * acoh * inv_d2)
                v = np.where(valid, Fs * D * mf.g2(ti, to, chi_i & chi_o) * jv / np.abs(ci), 0.0)
                value = v * np.where(t_ok, self.tint, 1.0)
            # Densities of the sampler from each side (visible normals of the side's direction).
            if mf.ggx:
                if ti is None:
                    ti = mf.terms(wi)
                ph_i = np.where(chi_i, mf.g1(ti) * acih * D / np.abs(ci), 0.0)
            else:
                # D·cos sampling; samples on microfacets facing away from the direction are rejected.
                ph = D * h[2]
                ph_i = np.where(chi_i, ph, 0.0)
            jf = np.where(r_ok, 0.25 / acoh, e2 * acoh * inv_d2)
            pf = np.where(valid, Fs * ph_i * jf, 0.0)
            if not need_rev:
                return value, pf, None
            if mf.ggx:
                if to is None:
                    to = mf.terms(wo)
                ph_o = np.where(chi_o, mf.g1(to) * acoh * D / np.abs(co), 0.0)
            else:
                ph_o = np.where(chi_o, ph, 0.0)
            jr = np.where(r_ok, 0.25 / acih, acih * inv_d2)
            pr = np.where(valid, Fs * ph_o * jr, 0.0)
        return value, pf, pr

    def sample(self, wi, rng, need_rev=True, pdf_only=False):
        """Sample a microfacet normal m (visible normals for GGX, D·cos for Beckmann), choose
        reflection with probability F(wi·m), else refract. The half vector of the pair is m
        itself (wi·h = wi·m, wo·h = 2(wi·m) − wi·m or cos θt), so value, densities and weight use
        ``eval``'s formulas without recomputing h; the weight is formed directly (D cancels)."""
        m = wi.shape[1]
        u = rng.random((3, m))
        ci = wi[2]
        live = ci != 0
        if not self.delta_only:
            mf, eta = self.mf, self.eta
            side = np.where(ci < 0, -1.0, 1.0)
            mm = mf.sample(wi * side, u[0], u[1])
            cim = wi[0] * mm[0] + wi[1] * mm[1] + ci * mm[2]
            # Fresnel and refraction geometry at the microfacet (materials/fresnel.py).
            e = np.where(cim >= 0, eta, 1.0 / eta)           # n(transmitted side)/n(incident side)
            c = np.minimum(np.abs(cim), 1.0)
            sin2_t = (1.0 - c * c) / (e * e)
            tir = sin2_t >= 1.0
            ct = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
            a, b = e * ct, e * c
            ds, dp = c + a, b + ct
            okd = (ds > 0) & (dp > 0)
            ds, dp = np.where(okd, ds, 1.0), np.where(okd, dp, 1.0)
            rs, rp = (c - a) / ds, (b - ct) / dp
            F = np.where(~tir & okd, 0.5 * (rs * rs + rp * rp), 1.0)
            cos_t = np.where(tir, 0.0, np.where(cim >= 0, -ct, ct))
            choose_r = u[2] < F
            inv_e = 1.0 / e
            ka = np.where(choose_r, 2.0 * cim, cim * inv_e + cos_t)
            kb = np.where(choose_r, -1.0, -inv_e)
            wo = np.stack([ka * mm[0] + kb * wi[0], ka * mm[1] + kb * wi[1], ka * mm[2] + kb * ci])
            co = wo[2]
            coh = np.where(choose_r, cim, cos_t)
            # The chosen lobe must land on its side (a reflection below the surface, or a
            # refraction that stays above, is a failed sample), on a front-facing microfacet.
            cc = co * ci
            side_ok = np.where(choose_r, cc > 0, (cc < 0) & (cos_t != 0))
            ok = live & (cim * ci > 0) & side_ok & ~self.smooth
            chi_o = coh * co > 0
            ti, to = mf.terms(wi), mf.terms(wo)
            g2 = mf.g2(ti, to, ok & chi_o)
            aci = np.abs(ci)
            acih = np.abs(cim)
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                if mf.ggx:
                    w1 = g2 * (1.0 + ti)                      # G2/G1(wi)
                else:
                    w1 = g2 * acih / (aci * mm[2])            # G2·|wi·m|/(|cos θi| cos θm)
                w1 = np.where(ok, w1, 0.0)
                if need_rev or pdf_only:
                    D = mf.D(mm)
                    acoh = np.abs(coh)
                    den = cim + e * coh
                    inv_d2 = 1.0 / (den * den)
                    Fs = np.where(choose_r, F, 1.0 - F)
                    if mf.ggx:
                        ph_i = acih * D / (aci * (1.0 + ti))
                        ph_o = np.where(chi_o, acoh * D / (np.abs(co) * (1.0 + to)), 0.0)
                    else:
                        ph_i = D * mm[2]
                        ph_o = np.where(chi_o, ph_i, 0.0)
                    pf = np.where(ok, Fs * ph_i * np.where(choose_r, 0.25 / acoh, e * e * acoh * inv_d2), 0.0)
                    pr = np.where(ok, Fs * ph_o * np.where(choose_r, 0.25 / acih, acih * inv_d2), 0.0)
                    w1 = np.where(pf > 0, w1, 0.0)   # a density that underflowed: a failed sample
                else:
                    pf = pr = ok * 1.0
                weight = (pf > 0) * 1.0 if pdf_only else w1 * np.where(choose_r, 1.0, self.tint)
            delta = np.zeros(m, bool)
        else:
            wo = np.zeros((3, m))
            weight = np.zeros((3, m))
            pf = pr = np.zeros(m)
            delta = np.zeros(m, bool)
        if np.any(self.smooth):
            sm = np.broadcast_to(self.smooth, (m,)) & live
            F, cos_t, e = fresnel_dielectric(ci, self.eta)
            choose_r = u[2] < F
            wo_d = np.where(choose_r, np.stack([-wi[0], -wi[1], ci]),
                            np.stack([-wi[0] / e, -wi[1] / e, cos_t]))
            w_d = np.where(choose_r, 1.0, self.tint)
            wo = np.where(sm, wo_d, wo)
            weight = np.where(sm, w_d, weight)
            pf = np.where(sm, 1.0, pf)
            pr = np.where(sm, 1.0, pr)
            delta = sm
        return wo, weight, pf, pr, delta


class GenericKernel(Kernel):
    """Any BSDF through the standard interface (e.g. a nested layered BSDF)."""

    generic = True

    def __init__(self, bsdf):
        self.bsdf = bsdf
        self.delta_only = bool(getattr(bsdf, "delta_only", False))
        self.transmissive = bool(getattr(bsdf, "transmissive", False))

    def take(self, idx):
        return GenericKernel(self.bsdf.take(idx))

    def sample(self, wi, rng, need_rev=True, pdf_only=False):
        a = np.ascontiguousarray(wi.T)
        s = self.bsdf.sample(a, rng, IMPORTANCE)
        delta = np.asarray(s.delta, dtype=bool)
        pf = np.where(delta, 1.0, s.pdf)
        pr = np.ones(a.shape[0])
        nd = np.flatnonzero(~delta) if need_rev else np.zeros(0, dtype=np.int64)
        if nd.size:
            b = self.bsdf if nd.size == a.shape[0] else self.bsdf.take(nd)
            pr[nd] = b.pdf(s.wo[nd], a[nd], rng, IMPORTANCE)
        return np.ascontiguousarray(s.wo.T), np.ascontiguousarray(s.weight.T), pf, pr, delta

    def eval(self, wi, wo, rng, need_rev=True, pdf_only=False):
        a, b = np.ascontiguousarray(wi.T), np.ascontiguousarray(wo.T)
        val = self.bsdf.eval(a, b, rng, IMPORTANCE)
        pf = self.bsdf.pdf(a, b, rng, IMPORTANCE)
        pr = self.bsdf.pdf(b, a, rng, IMPORTANCE) if need_rev else None
        return np.ascontiguousarray(val.T), pf, pr


def kernel_for(bsdf) -> Kernel:
    from .stack import NullBSDF
    if isinstance(bsdf, NullBSDF):
        return NullKernel()
    if type(bsdf) is DielectricBSDF:
        if np.all(np.asarray(bsdf.eta) == 1.0):
            # Equal indices on both sides: every microfacet refracts straight through, a delta
            # transmission (the microfacet BTDF's half vector degenerates to 0/0 there).
            return NullKernel(rgb_rows(bsdf.tint))
        return DielectricKernel.of(bsdf)
    if type(bsdf) is ConductorBSDF:
        return ConductorKernel.of(bsdf)
    if type(bsdf) is DiffuseBSDF:
        return DiffuseKernel.of(bsdf)
    return GenericKernel(bsdf)


class FramedKernel(Kernel):
    """An interface with a shading normal (per-interface normal map): the inner kernel works in
    the shading frame (z = n, x = the UV tangent made orthogonal to n), so its weights and values
    carry |⟨n, d⟩| instead of |cos d|. Directions on different sides of the shading and the
    geometric normal are rejected (value, density and weight 0), as in Guo et al.'s code.

    ``arrival(w)``: the factor |⟨n, w⟩| / |w_z| a walk multiplies in when it reaches this
    interface along −w: with it every segment carries Guo's symmetric term
    τ·|⟨n_a, d⟩|·|⟨n_b, d⟩| / |cos d| (digest §2)."""

    framed = True

    def __init__(self, inner: Kernel, n, s=None, t=None):
        self.inner = inner
        self.n = n                      # (3, 1|m) unit shading normals, n_z > 0
        self.delta_only = inner.delta_only
        self.transmissive = inner.transmissive
        if s is None:
            x = np.array([[1.0], [0.0], [0.0]]) - n[0:1] * n   # tangent: x projected off n
            ok = np.sqrt(dot3(x, x)) > 1e-6
            x = np.where(ok, x, np.array([[0.0], [1.0], [0.0]]) - n[1:2] * n)
            s = normalize3(x)
            t = np.stack([n[1] * s[2] - n[2] * s[1], n[2] * s[0] - n[0] * s[2], n[0] * s[1] - n[1] * s[0]])
        self.s, self.t = s, t
        self.constant = n.shape[1] == 1 and inner.constant

    def take(self, idx):
        if self.constant:
            return self
        if self.n.shape[1] == 1:
            return FramedKernel(self.inner.take(idx), self.n, self.s, self.t)
        return FramedKernel(self.inner.take(idx), self.n[:, idx], self.s[:, idx], self.t[:, idx])

    def _local(self, w):
        return np.stack([dot3(w, self.s), dot3(w, self.t), dot3(w, self.n)])

    def _world(self, w):
        return w[0] * self.s + w[1] * self.t + w[2] * self.n

    def arrival(self, w):
        c = dot3(w, self.n)
        return np.where(c * w[2] > 0, sdiv(np.abs(c), np.abs(w[2])), 0.0)

    def sample(self, wi, rng, need_rev=True, pdf_only=False):
        li = self._local(wi)
        lo, w, pf, pr, dl = self.inner.sample(li, rng, need_rev, pdf_only)
        wo = self._world(lo)
        ok = (li[2] * wi[2] > 0) & (lo[2] * wo[2] > 0)
        return wo, np.where(ok, w, 0.0), np.where(ok, pf, 0.0), np.where(ok, pr, 0.0), dl

    def mask_terms(self, w):
        return self.inner.mask_terms(self._local(w))

    def eval(self, wi, wo, rng, need_rev=True, pdf_only=False, ti=None, to=None):
        li, lo = self._local(wi), self._local(wo)
        if ti is None and to is None:
            v, pf, pr = self.inner.eval(li, lo, rng, need_rev, pdf_only)
        else:
            v, pf, pr = self.inner.eval(li, lo, rng, need_rev, pdf_only, ti=ti, to=to)
        ok = (li[2] * wi[2] > 0) & (lo[2] * wo[2] > 0)
        return (None if v is None else np.where(ok, v, 0.0), np.where(ok, pf, 0.0),
                None if pr is None else np.where(ok, pr, 0.0))
