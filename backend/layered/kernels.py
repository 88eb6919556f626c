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
from ..materials.specfun import SQRT_PI, erfc

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


def rgb_rows(v) -> np.ndarray:
    """(1, 3) / (n, 3) RGB parameter → (3, 1) / (3, n)."""
    return np.ascontiguousarray(np.asarray(v, dtype=np.float64).reshape(-1, 3).T)


def lanes_rows(v, idx):
    """Subset a (3, 1|n) row parameter."""
    return v if v.shape[1] == 1 else v[:, idx]


class Microfacet3:
    """GGX / Beckmann NDF, Smith Λ and sampling on (3, m) vectors (see materials/microfacet.py)."""

    def __init__(self, distribution, masking, au, av):
        self.ggx = distribution == GGX
        self.separable = masking == SEPARABLE
        self.au = np.maximum(np.asarray(au, dtype=np.float64), ALPHA_MIN)
        self.av = np.maximum(np.asarray(av, dtype=np.float64), ALPHA_MIN)

    def take(self, idx):
        return Microfacet3(GGX if self.ggx else BECKMANN, SEPARABLE if self.separable else "",
                           lanes(self.au, idx), lanes(self.av, idx))

    def D(self, m):
        x, y, z = m
        au, av = self.au, self.av
        z2 = z * z
        if self.ggx:
            k = x * x / (au * au) + y * y / (av * av) + z2
            d = sdiv(INV_PI / (au * av), k * k)
        else:
            e = sdiv(x * x / (au * au) + y * y / (av * av), z2)
            d = sdiv(np.exp(-e) * (INV_PI / (au * av)), z2 * z2)
        return np.where(z > 0, d, 0.0)

    def _s(self, w):
        x, y, z = w
        return (self.au * self.au * x * x + self.av * self.av * y * y) / np.maximum(z * z, 1e-300)

    def lam(self, w):
        """Exact Smith Λ(w)."""
        s = self._s(w)
        if self.ggx:
            return s / (2.0 * (1.0 + np.sqrt(1.0 + s)))
        a = np.maximum(1.0 / np.sqrt(np.maximum(s, 1e-200)), 1e-150)
        small = a < 6.0
        a_s = np.where(small, a, 1.0)
        v = 0.5 * (np.exp(-a_s * a_s) / (a_s * SQRT_PI) - erfc(a_s))
        return np.where(small, np.maximum(v, 0.0), 0.0)

    def g1_separable(self, w):
        """Mitsuba/Walter rational Beckmann G1 (without the side test); GGX exact."""
        if self.ggx:
            return 1.0 / (1.0 + self.lam(w))
        a = 1.0 / np.sqrt(np.maximum(self._s(w), 1e-200))
        return np.where(a < 1.6, (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a), 1.0)

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
            r = np.sqrt(-np.log1p(-np.minimum(u0, np.nextafter(1.0, 0.0))))
            phi = 2.0 * np.pi * u1
            mm = normalize3(np.stack([-self.au * r * np.cos(phi) * np.ones(m),
                                      -self.av * r * np.sin(phi) * np.ones(m), np.ones(m)]))
        flat = mm[2] <= 0
        if flat.any():
            mm[:, flat] = np.array([[0.0], [0.0], [1.0]])
        return mm


class Kernel:
    delta_only = False
    transmissive = False
    generic = False
    framed = False     # has a shading normal (FramedKernel): walks apply ``arrival`` factors

    def arrival(self, w):
        return 1.0


class NullKernel(Kernel):
    """Index-matched pass-through (optionally tinted): a delta transmission wo = −wi."""

    delta_only = True
    transmissive = True

    def __init__(self, tint=None):
        self.tint = tint  # (3, 1|n) or None

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

    @classmethod
    def of(cls, b: ConductorBSDF):
        mf = None if b.delta_only else Microfacet3(b.distribution, b.masking, b.alpha_u, b.alpha_v)
        return cls(rgb_rows(b.eta), rgb_rows(b.k), rgb_rows(b.tint), mf, np.asarray(b.smooth))

    def take(self, idx):
        return ConductorKernel(lanes_rows(self.eta, idx), lanes_rows(self.k, idx),
                               lanes_rows(self.tint, idx), None if self.mf is None else self.mf.take(idx),
                               lanes(self.smooth, idx))

    def _fresnel(self, c):
        return fresnel_conductor(c[None, :], self.eta, self.k) * self.tint

    def eval(self, wi, wo, rng, need_rev=True, pdf_only=False):
        m = wi.shape[1]
        if self.delta_only:
            return np.zeros((3, m)), np.zeros(m), np.zeros(m)
        # Two-sided: a query from below is mirrored into the upper hemisphere.
        s = np.where(wi[2] < 0, -1.0, 1.0)
        ci, co = wi[2] * s, wo[2] * s
        ok = (ci > 0) & (co > 0) & ~self.smooth
        wis = np.stack([wi[0], wi[1], ci])
        wos = np.stack([wo[0], wo[1], co])
        h = normalize3(wis + wos)
        cih = dot3(wis, h)
        mf = self.mf
        D = mf.D(h)
        g2, g1i, g1o = mf.masking(wis, wos, cih > 0, cih > 0)
        value = None if pdf_only else self._fresnel(cih) * np.where(ok, sdiv(D * g2, 4.0 * ci), 0.0)
        if mf.ggx:
            pf = sdiv(g1i * D, 4.0 * ci)
            pr = sdiv(g1o * D, 4.0 * co)
        else:
            pf = pr = sdiv(D * h[2], 4.0 * cih)
        return value, np.where(ok, pf, 0.0), np.where(ok, pr, 0.0)

    def sample(self, wi, rng, need_rev=True, pdf_only=False):
        m = wi.shape[1]
        s = np.where(wi[2] < 0, -1.0, 1.0)
        wis = np.stack([wi[0], wi[1], wi[2] * s])
        front = wis[2] > 0
        if not self.delta_only:
            u = rng.random((2, m))
            mm = self.mf.sample(wis, u[0], u[1])
            c = dot3(wis, mm)
            wo_s = 2.0 * c * mm - wis
            wo = np.stack([wo_s[0], wo_s[1], wo_s[2] * s])
            val, pf, pr = self.eval(wi, wo, rng, need_rev, pdf_only)
            ok = (pf > 0) & front & (c > 0)
            weight = ok * 1.0 if pdf_only else np.where(ok, val / np.where(ok, pf, 1.0), 0.0)
            pf = np.where(ok, pf, 0.0)
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
            weight = np.where(sm, self._fresnel(wis[2]), weight)
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

    @classmethod
    def of(cls, b: DielectricBSDF):
        mf = None if b.delta_only else Microfacet3(b.distribution, b.masking, b.alpha_u, b.alpha_v)
        return cls(b.eta, rgb_rows(b.tint), mf, np.asarray(b.smooth))

    def take(self, idx):
        return DielectricKernel(lanes(self.eta, idx), lanes_rows(self.tint, idx),
                                None if self.mf is None else self.mf.take(idx), lanes(self.smooth, idx))

    def eval(self, wi, wo, rng, need_rev=True, pdf_only=False):
        m = wi.shape[1]
        if self.delta_only:
            return np.zeros((3, m)), np.zeros(m), np.zeros(m)
        mf = self.mf
        eta = self.eta
        ci, co = wi[2], wo[2]
        refl = ci * co > 0
        trans = ci * co < 0
        e = np.where(ci > 0, eta, 1.0 / eta)          # n(wo side)/n(wi side) for transmission
        h = np.where(refl, wi + wo, wi + e * wo)
        h = normalize3(h)
        h = h * np.where(h[2] < 0, -1.0, 1.0)
        okh = h[2] > 0
        cih, coh = dot3(wi, h), dot3(wo, h)
        F = fresnel_dielectric(cih, eta)[0]
        rough = ~self.smooth
        refl = refl & okh & (cih * coh > 0) & rough
        trans = trans & okh & (cih * coh < 0) & rough
        D = mf.D(h)
        g2, g1i, g1o = mf.masking(wi, wo, cih * ci > 0, coh * co > 0)
        aci, aco = np.abs(ci), np.abs(co)
        den_i = cih + e * coh
        if pdf_only:
            value = None
        else:
            DG = D * g2
            fr = sdiv(F * DG, 4.0 * aci)
            ft = sdiv((1.0 - F) * DG * np.abs(cih * coh), aci * den_i * den_i) * (e * e)
            value = np.where(refl, fr, 0.0) + np.where(trans, ft, 0.0) * self.tint
        # Densities of the sampler from each side (visible normals of the side's direction).
        if mf.ggx:
            ph_i = sdiv(g1i * np.abs(cih) * D, aci)
            ph_o = sdiv(g1o * np.abs(coh) * D, aco)
        else:
            # D·cos sampling; samples on microfacets facing away from the direction are rejected.
            ph = D * h[2]
            ph_i = np.where(cih * ci > 0, ph, 0.0)
            ph_o = np.where(coh * co > 0, ph, 0.0)
        pf_r = sdiv(F * ph_i, 4.0 * np.abs(coh))
        pf_t = sdiv((1.0 - F) * ph_i * e * e * np.abs(coh), den_i * den_i)
        pf = np.where(refl, pf_r, 0.0) + np.where(trans, pf_t, 0.0)
        if not need_rev:
            return value, pf, None
        e_r = 1.0 / e
        den_o = coh + e_r * cih
        pr_r = sdiv(F * ph_o, 4.0 * np.abs(cih))
        pr_t = sdiv((1.0 - F) * ph_o * e_r * e_r * np.abs(cih), den_o * den_o)
        pr = np.where(refl, pr_r, 0.0) + np.where(trans, pr_t, 0.0)
        return value, pf, pr

    def sample(self, wi, rng, need_rev=True, pdf_only=False):
        m = wi.shape[1]
        u = rng.random((3, m))
        ci = wi[2]
        live = ci != 0
        side = np.where(ci < 0, -1.0, 1.0)
        if not self.delta_only:
            ws = wi * side
            mm = self.mf.sample(ws, u[0], u[1])
            cim = dot3(wi, mm)
            F, cos_t, e = fresnel_dielectric(cim, self.eta)
            choose_r = u[2] < F
            wo_r = 2.0 * cim * mm - wi
            wo_t = -wi / e + (cim / e + cos_t) * mm
            wo = np.where(choose_r, wo_r, wo_t)
            val, pf, pr = self.eval(wi, wo, rng, need_rev, pdf_only)
            if pr is None:
                pr = pf  # not needed (a walk that records nothing); any finite placeholder
            # The chosen lobe must land on its side (a reflection below the surface, or a
            # refraction that stays above, is a failed sample), on a front-facing microfacet.
            side_ok = np.where(choose_r, wo[2] * ci > 0, (wo[2] * ci < 0) & (cos_t != 0))
            ok = live & (pf > 0) & (cim * ci > 0) & side_ok
            weight = ok * 1.0 if pdf_only else np.where(ok, val / np.where(ok, pf, 1.0), 0.0)
            pf = np.where(ok, pf, 0.0)
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

    def take(self, idx):
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

    def eval(self, wi, wo, rng, need_rev=True, pdf_only=False):
        li, lo = self._local(wi), self._local(wo)
        v, pf, pr = self.inner.eval(li, lo, rng, need_rev, pdf_only)
        ok = (li[2] * wi[2] > 0) & (lo[2] * wo[2] > 0)
        return (None if v is None else np.where(ok, v, 0.0), np.where(ok, pf, 0.0),
                None if pr is None else np.where(ok, pr, 0.0))
