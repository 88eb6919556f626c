"""Uniform layered stacks solved once, when the scene loads, by adding-doubling in a Fourier basis
over the azimuth (the method of Jakob, d'Eon, Jakob and Marschner 2014, written here from the
equations); backend/kernels/bsdf/tabulated.py evaluates and samples the table without noise.

Which stacks (``plan``): untextured, opaque (the last interface a conductor or a diffuse body),
isotropic (no ``roughness_v``, no normal or bump maps, media whose phase function depends only on
the scattering angle: isotropic, HG, vMF, Rayleigh), a dielectric or null top, inner interfaces null or
rough dielectrics, every rough element at least ``ALPHA_MIN`` rough (sharper lobes need more
nodes than a table of bounded size holds), under ``"estimator": "auto"``. A stack with a closed
form (layered/coated_diffuse.py) takes that instead; everything else keeps the walk.

The method. Directions in each slab are nodes μ_k uniform in θ with trapezoid weights w_k (``_grid``) per
hemisphere;
each layer (interface or slab) is four flux kernels (reflection and transmission from above and
from below: the flux density per steradian leaving per unit flux arriving, importance transport,
propagation azimuths) expanded as Σ_m k_m(μ → μ') cos(mΔφ). At order m, the matrix
A[i, j] = c_m k_m(μ_j → μ_i) w_j (c_0 = 2π, c_m = π) composes by matrix products, so layers add by
  R = R1 + T1↑ (I − R2 R1↓)⁻¹ R2 T1↓          (application order right to left)
from the bottom up. Interfaces are sampled from the walk's own interface code on a grid of Δφ and
projected (trapezoid rule on [0, π]; kernels/layered/tabulate.py); a slab starts as a layer of
optical depth τ/2^K ≤ DTAU0 in single scattering (exact for that layer) and doubles K times;
orders beyond its phase function's content only attenuate. The top interface stays out of the
table where it is sharp: a smooth (or nearly smooth, α ≤ ALPHA_SMOOTH) top keeps the table in the
top medium's directions, refracted exactly at evaluation; its own reflection is always evaluated
exactly (kernels/bsdf/tabulated.py).

Resolution: n nodes and M orders from the sharpest lobe (the smallest α of a rough element in the
table, or 1 − |g| of an HG medium): n = 6.4/α (32 to 128), M = 4/α (16 to 128); measured on Guo
et al.'s Fig. 2 stack (α 0.05 coat and copper): twice the orders change nothing, half the nodes
double the error at the highlight's peak and shoulders (docs/materials.md).
Approximations (stated with their measured error in docs/materials.md and tests/test_tabulated.py):
the finite nodes and orders, bilinear interpolation between nodes, and for a nearly smooth top its
refraction taken as smooth. Tables are cached per process and on disk (the kernel cache folder,
tables/<hash of the bound stack, the settings and this file>.npy), so a stack is solved once per
machine.
"""
from __future__ import annotations

import hashlib
import math
import os
import time
from pathlib import Path

import numpy as np

ALPHA_MIN = 0.03            # sharper rough elements keep the walk
ALPHA_SMOOTH = 0.025        # a top at most this rough refracts as a smooth one (its reflection stays exact)
N_RANGE = (48, 128)
M_RANGE = (16, 128)
DTAU0 = 2.0 ** -13          # the optical depth a slab starts from (single scattering)
START_FRACTION = 0.001       # ... and at most this fraction of the grazing node's μ (an albedo-1 slab of τ 8 kept 99.4 % of its light at 1 %, 99.92 % at 0.1 %, 99.995 % at 0.01 %)
GRID = 96                   # GRID² microfacet normals project an interface per node (a Fibonacci lattice)
BANDWIDTH = 8.0             # a sampled interface keeps its first 8/α azimuthal orders
POLE_REFINE = 0.5           # node spacing at the pole: 1 − POLE_REFINE times the uniform one
S_I, S_O, S_B = 32, 48, 64  # the sampler's nodes in θi, cells in θo, bins in Δφ
TRUNCATE = 1e-4             # a node pair's orders below this share of its order 0 are left out
PHASES = ("isotropic", "hg", "vmf", "rayleigh")


# ----------------------------------------------------------------------------- which stacks
def _alpha(m) -> float | None:
    """A constant isotropic roughness (None: anisotropic or textured)."""
    if m.roughness_v is not m.roughness and not (m.roughness_v.is_constant and m.roughness.is_constant
                                                 and float(m.roughness_v.mean()) == float(m.roughness.mean())):
        return None
    return float(np.asarray(m.roughness.mean()).reshape(-1)[0])


def _textured_body_only(flat) -> bool:
    """Is the diffuse body's colour the stack's only texture?"""
    *above, body = flat.interfaces
    return (getattr(body, "type_name", "") == "diffuse" and body.uses_textures
            and not any(getattr(m, "uses_textures", False) for m in above)
            and not any(m.uses_textures for m in flat.media))


def plan(material, flat) -> dict | None:
    """The tabulation's settings for a stack, or None (the walk)."""
    body = material.uses_textures and _textured_body_only(flat)
    if (material.uses_textures and not body) or flat.transmissive or any(n is not None for n in flat.normals):
        return None
    ifaces = flat.interfaces
    if len(ifaces) < 2:
        return None
    sharp = []                                       # widths of the lobes inside the table
    top, bottom = ifaces[0], ifaces[-1]
    kinds = [getattr(m, "type_name", "null") for m in ifaces]
    if kinds[0] not in ("dielectric", "null") or kinds[-1] not in ("conductor", "diffuse"):
        return None
    top_alpha = 0.0
    if kinds[0] == "dielectric":
        top_alpha = _alpha(top)
        if top_alpha is None or (ALPHA_SMOOTH < top_alpha < ALPHA_MIN):
            return None
        # never rougher than nothing but below the kernels' smallest roughness, which they
        # evaluate the top's lobe with (1e-320 in a fuzzed scene divided by zero there)
        from ..kernels.microfacet_codes import ALPHA_MIN as KERNEL_ALPHA_MIN
        if top_alpha > 0.0:
            top_alpha = max(top_alpha, KERNEL_ALPHA_MIN)
        if top_alpha > ALPHA_SMOOTH:
            sharp.append(top_alpha)
    for m, kind in zip(ifaces[1:-1], kinds[1:-1]):
        if kind == "null":
            continue
        a = _alpha(m) if kind == "dielectric" else None
        if a is None or a < ALPHA_MIN:
            return None
        sharp.append(a)
    if kinds[-1] == "conductor":
        a = _alpha(bottom)
        if a is None or a < ALPHA_MIN:              # a smooth metal keeps the walk too (a delta)
            return None
        if a > 0.0:
            sharp.append(a)
    for spec in flat.media:
        if spec.phase.type_name not in PHASES:
            return None
        # a phase function's lobe width: 1 − |g| for HG, 1/√κ for vMF (sharper: the walk)
        if spec.phase.type_name == "hg":
            width = 1.0 - abs(float(np.asarray(spec.phase.params["g"].mean()).reshape(-1)[0]))
        elif spec.phase.type_name == "vmf":
            width = 1.0 / math.sqrt(max(float(np.asarray(spec.phase.params["kappa"].mean()).reshape(-1)[0]), 1e-6))
        else:
            width = 1.0
        if width < ALPHA_MIN:
            return None
        sharp.append(width)
    a = min(sharp) if sharp else 1.0
    n = int(np.clip(math.ceil(6.4 / a), *N_RANGE))
    M = int(np.clip(math.ceil(4.0 / a), *M_RANGE))
    return {"rough_top": top_alpha > ALPHA_SMOOTH, "top_alpha": top_alpha, "n": n, "M": M, "body": bool(body)}


# ----------------------------------------------------------------------------- the solver
def _grid(n: int, split: float | None = None):
    """Nodes and weights over μ = |cos θ| ∈ [0, 1]: n + 1 nodes uniform in θ from the pole (μ = 1,
    where a function on the sphere has no azimuthal orders) to grazing (μ = 1e-4), and the
    trapezoid weights, which are exactly the integrals of the nodes' linear "hat" functions
    (the grazing node sits at a quarter of its neighbour's μ and takes everything below it).
    So a flux shared between the two nodes around a direction by the hats (the interfaces'
    projection, kernels/layered/tabulate.py) keeps its total under this quadrature and reads back
    as the local density; the quadrature, the projection and the evaluation's linear
    interpolation are one piecewise-linear representation. (Gauss nodes were tried first: their
    end weights are 22 % smaller than the end hats, which lost 7 % of a lobe at the pole.)
    ``split``: θ is uniform on each side of this μ, which is a node: the critical angle of total
    internal reflection under a smooth top, where the integrands jump."""
    if split is None or not 0.05 < split < 0.95:
        theta = 0.5 * math.pi * _towards_pole(np.linspace(0.0, 1.0, n + 1))
    else:
        ts = math.acos(split)
        k = max(2, int(round(n * ts / (0.5 * math.pi))))
        # Inside the escape cone the reflectance leaves 1 as √(μ − split): nodes uniform in u
        # with θ = ts·(1 − u²), in which it is smooth (a smooth coat over a diffuse body, 32
        # nodes: 1.55 % → 0.18 % against the closed form; first order in the node spacing before)
        u = np.linspace(0.0, 1.0, k + 1)
        cone = ts * (1.0 - u * u * (3.0 - 2.0 * u))      # also fine at the pole (u = 1)
        theta = np.concatenate([cone[::-1], np.linspace(ts, 0.5 * math.pi, n - k + 1)[1:]])
    mu = np.sort(np.cos(theta))
    mu[0] = 0.25 * mu[1]                          # grazing (μ = 0 would divide by zero in the slabs)
    mu[-1] = 1.0
    w = np.empty(mu.size)
    w[1:-1] = 0.5 * (mu[2:] - mu[:-2])
    w[0] = mu[0] + 0.5 * (mu[1] - mu[0])          # the first node takes everything below it
    w[-1] = 0.5 * (mu[-1] - mu[-2])
    return np.ascontiguousarray(mu), w


def _towards_pole(u):
    """[0, 1] → [0, 1], four times finer than uniform at 0 (the pole), 1.75 times coarser at 1
    (grazing): near the pole the azimuthal orders behave as sin^m θ, which the linear rule in μ
    follows only at a fine spacing (measured: a rough coat over copper read +10 % at normal
    incidence with uniform θ, converging only linearly with the nodes)."""
    return u - (POLE_REFINE / math.pi) * np.sin(math.pi * u)


def _projector(M: int):
    """(Δφ samples on [0, π], matrix C with samples @ C = the cosine coefficients 0 … M − 1)."""
    q = 4 * M + 1
    phis = np.linspace(0.0, math.pi, q)
    t = np.full(q, math.pi / (q - 1))
    t[0] *= 0.5
    t[-1] *= 0.5
    eps = np.full(M, 2.0)
    eps[0] = 1.0
    C = (t[:, None] * np.cos(np.outer(phis, np.arange(M)))) * (eps / math.pi)[None, :]
    return np.ascontiguousarray(phis), C


def _orders(M: int) -> np.ndarray:
    c = np.full(M, math.pi)
    c[0] = 2.0 * math.pi
    return c


class _Solver:
    def __init__(self, B, FT, n: int, M: int, split: float | None = None):
        self.B, self.FT, self.M = B, FT, M
        self.mu, self.w = _grid(n, split)
        self.n = n = self.mu.size
        self.phis, self.C = _projector(M)
        self.cm = _orders(M)
        self.eye = np.eye(n)

    def matrices(self, k: np.ndarray) -> np.ndarray:
        """Coefficients k (n_in, n_out, M, 3) → A (M, 3, n_out, n_in)."""
        A = np.transpose(k, (2, 3, 1, 0)) * self.cm[:, None, None, None] * self.w[None, None, None, :]
        return np.ascontiguousarray(A)

    def _project(self, o: int, s_in: float):
        """Cosine coefficients (n, n, M, 3) of the interface's reflection and transmission for
        light arriving from above (s_in = +1) or below (−1), projected through the interface's
        own sampler (kernels/layered/tabulate.py): its flux kept exactly however narrow the
        lobe, read back as a local average over the node spacing. (Sampling the kernel at the
        nodes instead was tried: +7 % near the pole for a coat of α 0.3, whose azimuthal orders
        behave as sin^m θ there, which no linear rule in μ follows.)"""
        from ..kernels.layered.iface import IF_KIND, IF_P
        from ..kernels.layered.tabulate import interface_projection
        from ..kernels.materials import CONDUCTOR
        n, B = self.n, self.B
        alpha = B[o + IF_P + (9 if B[o + IF_KIND] == CONDUCTOR else 4)]
        refl = np.zeros((n, n, self.M, 3))
        trans = np.zeros((n, n, self.M, 3))
        _in_threads(lambda j0, j1: interface_projection(B, o, self.mu, j0, j1, s_in, self.w, GRID, refl, trans), n)
        # Orders beyond the lobe's own bandwidth hold only the projection's sampling noise, which
        # the series would add up coherently at Δφ = 0 (measured: a copper lobe of α 0.3 under a
        # coat of α 0.05 read 0.02 instead of 0.6 at its mirror direction).
        keep = int(math.ceil(BANDWIDTH / max(alpha, 1e-3)))
        refl[:, :, keep:] = 0.0
        trans[:, :, keep:] = 0.0
        return refl, trans

    def _pole_rows(self, k, k_back, factor):
        """The flux every node sends to the pole, from what the pole sends to every node (the
        reverse kernel ``k_back``) by reciprocity: k(j → pole)/μ_pole = factor·k_back(pole → j)/μ_j.
        The pole's own cap receives a few per cent of the samples, too few for its density, while
        light arriving at the pole sends all of them (a rough coat over copper read +10 % at
        normal incidence before). The pole has no azimuthal orders."""
        mu = self.mu
        k[:, -1, 0] = factor * k_back[-1, :, 0] * (mu[-1] / mu)[:, None]
        k[:, -1, 1:] = 0.0

    def interface(self, o: int):
        """The interface's matrices: (Ra, Td, Rb, Tu) — reflection from above, transmission
        down, reflection from below, transmission up (a conductor: (Ra, None, None, None))."""
        from ..kernels.layered.iface import IF_KIND, IF_P
        from ..kernels.materials import DIELECTRIC
        ra, td = self._project(o, 1.0)
        self._pole_rows(ra, ra, 1.0)
        if self.B[o + IF_KIND] != DIELECTRIC:
            return self.matrices(ra), None, None, None
        rb, tu = self._project(o, -1.0)
        self._pole_rows(rb, rb, 1.0)
        # generalised reciprocity across the interface (importance transport; n_below/n_above
        # = η): k_down(j → i)/μ_i = η²·k_up(i → j)/μ_j (checked on the projections' well-sampled
        # pairs: within their sampling error)
        eta2 = float(self.B[o + IF_P]) ** 2
        td_back, tu_back = td.copy(), tu.copy()
        self._pole_rows(td, tu_back, eta2)
        self._pole_rows(tu, td_back, 1.0 / eta2)
        return self.matrices(ra), self.matrices(td), self.matrices(rb), self.matrices(tu)

    def delta_reflection(self, F: np.ndarray) -> np.ndarray:
        """A mirror with reflectance F (n, 3): diagonal in every order."""
        A = np.zeros((self.M, 3, self.n, self.n))
        idx = np.arange(self.n)
        A[:, :, idx, idx] = F.T[None, :, :]
        return A

    def medium(self, md: int):
        """The slab at block offset md: None (empty), or (R, T, mp, att): R and T (mp, 3, n, n)
        for the orders that scatter, att (3, n) the unscattered transmittance (the whole slab,
        and beyond order mp all of it: R = 0, T = diag(att))."""
        from ..kernels.layered.table import ABSORBING, EMPTY, M_ALB, M_KIND, M_PH, M_TAU
        B, n, mu, w = self.B, self.n, self.mu, self.w
        kind = int(B[md + M_KIND])
        tau = np.array(B[md + M_TAU:md + M_TAU + 3])
        if kind == EMPTY or not np.any(tau > 0.0):
            return None
        att = np.exp(-tau[:, None] / mu[None, :])                    # (3, n)
        if kind == ABSORBING:
            return None, None, 0, att
        from ..kernels.layered.tabulate import phase_samples
        alb = np.array(B[md + M_ALB:md + M_ALB + 3])
        same = np.empty((n, n, self.phis.size))
        opp = np.empty_like(same)
        phase_samples(B, md + M_PH, self.FT, mu, self.phis, same, opp)
        ps = np.einsum("jiq,qm->jim", same, self.C)
        po = np.einsum("jiq,qm->jim", opp, self.C)
        # Each direction's discretised phase function scatters exactly all the light it receives
        # (the node rule alone kept 99.4–100.2 % of an albedo-1 slab's light at 32 nodes, an
        # error that grows with the number of scattering events in a thick slab)
        total = 2.0 * math.pi * ((ps[:, :, 0] + po[:, :, 0]) * w[None, :]).sum(axis=1)
        ps /= total[:, None, None]
        po /= total[:, None, None]
        size = np.maximum(np.abs(ps).max(axis=(0, 1)), np.abs(po).max(axis=(0, 1)))
        keep = np.flatnonzero(size > 1e-7 * size[0])
        mp = int(keep[-1]) + 1 if keep.size else 1
        # single scattering is exact for a layer thin along every node's direction (DTAU0 alone
        # lost 1–3 % of an albedo-1 slab's light at grazing); the light a layer scatters twice
        # is missing, an energy error proportional to the start (START_FRACTION)
        start = min(DTAU0, START_FRACTION * float(mu[0]))
        K = max(0, int(math.ceil(math.log2(max(tau.max(), 1e-300) / start))))
        dt = tau / 2.0 ** K
        inv = 1.0 / mu
        R = np.empty((mp, 3, n, n))
        T = np.empty((mp, 3, n, n))
        s = inv[:, None] + inv[None, :]                              # [i, j]: 1/μ_i + 1/μ_j
        d = inv[None, :] - inv[:, None]                              # 1/μ_j − 1/μ_i
        for c in range(3):
            # single scattering in a layer of depth dt: in at μ_j (flux 1), scattered at depth
            # t with probability a·dt/μ_j·e^(−t/μ_j), out through the rest of the layer at μ_i
            rfac = -np.expm1(-dt[c] * s) / s * inv[None, :]
            small = np.abs(d * dt[c]) < 1e-9
            dd = np.where(small, 1.0, d)
            g = np.where(small, dt[c], -np.expm1(-dt[c] * dd) / dd)
            tfac = np.exp(-dt[c] * inv)[:, None] * g * inv[None, :]
            scale = self.cm[:mp, None, None] * alb[c] * w[None, None, :]
            R[:, c] = np.transpose(po[:, :, :mp], (2, 1, 0)) * scale * rfac[None]
            T[:, c] = np.transpose(ps[:, :, :mp], (2, 1, 0)) * scale * tfac[None]
        idx = np.arange(n)
        T[:, :, idx, idx] += np.exp(-dt[:, None] * inv[None, :])[None]
        def double(j0, j1):                                          # two equal halves, K times
            r, t = R[j0:j1], T[j0:j1]
            for _ in range(K):
                x = np.linalg.solve(self.eye - r @ r, t)
                r = r + t @ (r @ x)
                t = t @ x
            R[j0:j1], T[j0:j1] = r, t

        _in_threads(double, mp)                  # NumPy's solver and products release the GIL
        return R, T, mp, att

    def add_medium(self, below: np.ndarray, md: int) -> np.ndarray:
        """The reflection of a slab over ``below`` (both in this slab's directions)."""
        out = self.medium(md)
        if out is None:
            return below
        R, T, mp, att = out
        res = below * att[None, :, :, None] * att[None, :, None, :]      # R = 0, T = diag(att)
        if mp:
            Rb = below[:mp]
            res[:mp] = R + T @ np.linalg.solve(self.eye - Rb @ R, Rb @ T)
        return res

    def add_interface(self, below: np.ndarray, o: int):
        """(the reflection of a rough interface over ``below``, its own reflection from above)."""
        Ra, Td, Rb, Tu = self.interface(o)
        return Ra + Tu @ np.linalg.solve(self.eye - below @ Rb, below @ Td), Ra


def _in_threads(work, n: int) -> None:
    """work(j0, j1) over rows 0 … n − 1 in chunks on every core (the compiled kernels release
    the GIL and write disjoint rows)."""
    from concurrent.futures import ThreadPoolExecutor
    from ..limits import cpu_count
    workers = max(1, min(cpu_count(), n))
    bounds = np.linspace(0, n, 4 * workers + 1).astype(int)      # smaller pieces balance better
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for f in [pool.submit(work, int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]:
            f.result()


def _bottom(S: _Solver, o: int, kind: str, rho=None) -> np.ndarray:
    """The bottom interface's reflection from above (a diffuse body: of albedo ``rho`` if given)."""
    from ..kernels.layered.iface import IF_DELTA, IF_P
    B = S.B
    if kind == "diffuse":
        A = np.zeros((S.M, 3, S.n, S.n))
        rho = np.array(B[o + IF_P:o + IF_P + 3]) if rho is None else np.full(3, float(rho))
        # k_0 = ρ μ_i / π, A_0 = 2π k_0 w_j
        A[0] = 2.0 * rho[:, None, None] * S.mu[None, :, None] * S.w[None, None, :]
        return A
    if B[o + IF_DELTA] > 0.0:                                        # a smooth conductor
        from ..kernels.layered.tabulate import delta_reflectance
        F = np.empty((S.n, 3))
        delta_reflectance(B, o, S.mu, F)
        return S.delta_reflection(F)
    return S.interface(o)[0]


def solve(B: np.ndarray, FT: np.ndarray, kinds: list, settings: dict, rho=None) -> tuple[np.ndarray, np.ndarray, bool]:
    """(nodes μ, y (n, n, M, 3), whether the first interface's single reflection is left out of
    y) of a bound stack (kernels/bsdf/tabulated.py's layout); ``rho``: the diffuse body's albedo
    instead of the bound one."""
    from ..kernels.layered.table import M_TAU, if_offset, md_offset
    n, M = settings["n"], settings["M"]
    split = None
    if not settings["rough_top"] and kinds[0] == "dielectric":
        from ..kernels.layered.iface import IF_P
        eta = float(B[if_offset(0) + IF_P])
        if eta > 1.0:
            split = math.sqrt(1.0 - 1.0 / (eta * eta))     # inside: the escape cone's edge
    S = _Solver(B, FT, n, M, split)
    n = S.n
    N = len(kinds)
    R = _bottom(S, if_offset(N - 1), kinds[-1], rho)
    # the first interface's own reflection (not a textured body: its colour is per lane)
    first = R if N == 2 and not settings.get("body") else None
    for k in range(N - 2, -1, -1):
        R = S.add_medium(R, md_offset(k))
        if k > 0 and kinds[k] != "null":
            R, Ra = S.add_interface(R, if_offset(k))
            if k == 1:
                first = Ra
    if settings["rough_top"]:
        o = if_offset(0)
        _, Td, Rb, Tu = S.interface(o)
        X = Tu @ np.linalg.solve(S.eye - R @ Rb, R @ Td)
    else:
        # inside the top medium: light that the top reflects back down (total internal
        # reflection included) meets the stack again
        F = np.zeros((n, 3))
        if kinds[0] == "dielectric":
            from ..kernels.layered.iface import IF_P
            from ..kernels.fresnel import dielectric as fresnel
            eta = float(B[if_offset(0) + IF_P])
            F[:] = np.array([fresnel(-float(m), eta)[0] for m in S.mu])[:, None]
            if split is not None:
                # at the critical angle itself the reflectance jumps from 1 (total internal
                # reflection) to below 1: the trapezoid rule wants the mean of the two limits
                k = int(np.argmin(np.abs(S.mu - split)))
                F[k] = 0.5 * (fresnel(-split * (1.0 - 1e-9), eta)[0] + fresnel(-min(split * (1.0 + 1e-9), 1.0), eta)[0])
        X = np.linalg.solve(S.eye - R @ S.delta_reflection(F), R)
        if first is not None:
            # its single reflection through the unscattered top slab is evaluated exactly
            tau = np.array(B[md_offset(0) + M_TAU:md_offset(0) + M_TAU + 3])
            att = np.exp(-tau[:, None] / S.mu[None, :])
            X = X - first * att[None, :, :, None] * att[None, :, None, :]
    y = np.transpose(X, (3, 2, 0, 1)) / (S.cm[None, None, :, None] * S.w[:, None, None, None]
                                         * S.mu[None, :, None, None])
    # The pole has no azimuthal orders; the grazing node (a direction in the surface) carries no
    # information of its own: its neighbour's values, which the cosine then takes to zero.
    y[-1, :, 1:] = 0.0
    y[:, -1, 1:] = 0.0
    y[0] = y[1]
    y[:, 0] = y[:, 1]
    return S.mu, np.ascontiguousarray(y), first is not None and not settings["rough_top"]


# ----------------------------------------------------------------------------- the table block
def _top_reflection(B, o, kind: str, alpha: float, dist: int, masking: int, mu: np.ndarray):
    """The directional albedo of the top's own reflection at each μ."""
    if kind == "null":
        return np.zeros(mu.size)
    from ..kernels.bsdf.coated_diffuse import _interface_integrals
    from .coated_diffuse import STRATA
    from ..kernels.fresnel import dielectric as fresnel
    from ..kernels.layered.iface import IF_P
    from ..kernels.microfacet_codes import ALPHA_MIN
    eta = float(B[o + IF_P])
    if alpha <= 0.0:
        return np.array([fresnel(float(m), eta)[0] for m in mu])
    alpha = max(alpha, ALPHA_MIN)         # as the kernels clamp it (1e-320 divided by zero here)
    rs = np.empty(mu.size)
    for k, m in enumerate(mu):
        rs[k] = _interface_integrals(eta, (1.0, 1.0, 1.0), alpha, False, dist, masking,
                                     (0.0, 0.0, 0.0), max(float(m), 1e-4), STRATA)[1]
    return rs


def _bound_kinds(B, N: int) -> list:
    """The interfaces' kinds as the walk binds them (an index-matched dielectric is null)."""
    from ..kernels import materials as km
    from ..kernels.layered.iface import IF_KIND
    from ..kernels.layered.table import if_offset
    names = {km.DIFFUSE: "diffuse", km.CONDUCTOR: "conductor", km.DIELECTRIC: "dielectric"}
    return [names.get(int(B[if_offset(l) + IF_KIND]), "null") for l in range(N)]


def _identity(material):
    """(key, bound block, fiber table, interface kinds, settings) of a stack that qualifies, or
    None: the key hashes everything the table depends on."""
    from .flat import flatten
    flat = flatten(material)
    settings = plan(material, flat)
    if settings is None:
        return None
    ST, TX, sid = material.kernel_table()
    B = np.array(ST.bound[sid])
    if settings["body"]:
        # A textured body: the stack is bound anywhere (nothing else varies) and the body's own
        # colour is left out (the table is solved for albedos 0, ½ and 1; kernels/bsdf/tabulated.py)
        from ..kernels.layered.iface import IF_P
        from ..kernels.layered.table import UNIT_DUV, bind_into, if_offset
        bind_into(ST, TX, sid, 0.5, 0.5, UNIT_DUV, B)
        body = if_offset(len(flat.interfaces) - 1) + IF_P
        B[body:body + 3] = 0.0
    kinds = _bound_kinds(B, len(flat.interfaces))
    key = hashlib.sha1(B.tobytes() + repr((kinds, sorted(settings.items()))).encode() + _SOURCE).hexdigest()
    return key, B, np.ascontiguousarray(ST.FT), kinds, settings


def build(material) -> np.ndarray | None:
    """The table block of a layered material (None if it does not qualify): from this process's
    memory, the disk cache, or solved now (and kept in both)."""
    ident = _identity(material)
    if ident is None:
        return None
    key, B, FT, kinds, settings = ident
    block = _CACHE.pop(key, None)
    if block is None:
        block = _load(key)
        if block is None:
            block = _block(B, FT, kinds, settings)
            _SOLVED[0] += 1
            _store(key, block)
    _CACHE[key] = block                      # the newest last: the oldest go first
    while len(_CACHE) > CACHE_ENTRIES:
        del _CACHE[next(iter(_CACHE))]
    return block


def prepare(materials, emit) -> None:
    """Solve the tables of a scene's tabulated stacks before the workers start (this process keeps
    them, worker processes find them on disk), saying so when some must be solved (seconds each
    the first time on a machine): ``emit`` gets a "compiling" event before and a "compiled" one
    after, as the first compilation of the kernels does."""
    # layered materials (duck-typed: layered/material.py imports this module)
    todo = [m for m in materials if isinstance(getattr(type(m), "table_block", None), property)
            and m.options.estimator == "auto" and m.closed_form is None and not hasattr(m, "_table_block")]
    idents = [(m, _identity(m)) for m in todo]
    missing = {i[0] for _, i in idents if i is not None and i[0] not in _CACHE and not _cache_file(i[0]).exists()}
    t0 = time.perf_counter()
    if missing:
        emit({"event": "compiling", "message": f"solving {len(missing)} layered stack(s) into tables "
                                               f"(once per stack and machine) ..."})
    size = 0
    for m, _ in idents:
        block = m.table_block
        size += block.nbytes if block is not None else 0
    if missing:
        dt = time.perf_counter() - t0
        emit({"event": "compiled", "seconds": round(dt, 2), "bytes": int(size),
              "message": f"solved {len(missing)} layered stack(s) into tables in {dt:.1f} s, "
                         f"{size / 2 ** 20:.1f} MiB (cached in {_cache_file('x').parent})"})


_CACHE: dict = {}        # content hash of the bound stack → its block, for this process
#: Blocks kept in memory at most (a few MiB each). A scene's materials hold their own blocks; this
#: cache only saves reading the disk cache again, and must not grow without end in a long-lived
#: process (the render server, backend/cli/serve.py, renders scene after edited scene).
CACHE_ENTRIES = 32
_SOLVED = [0]            # tables solved (not loaded) by this process
# The solver's own source is part of a table's key (the kernel cache folder's key covers
# backend/kernels/, not this file).
_SOURCE = hashlib.sha1(Path(__file__).read_bytes()).digest()


def _cache_file(key: str) -> Path:
    from ..kernels.cache import configure
    return configure() / "tables" / f"{key}.npy"


def _load(key: str):
    """A table solved before on this machine (the kernel cache folder, keyed by the kernels'
    sources: tables/<content hash>.npy), or None."""
    try:
        block = np.load(_cache_file(key), allow_pickle=False)
    except (OSError, ValueError):
        return None
    block.setflags(write=False)
    return block


def _store(key: str, block: np.ndarray) -> None:
    """Keep a table for the next render (atomically: a partial file never has the final name).
    A cache that cannot be written only costs the solve next time."""
    try:
        path = _cache_file(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npy")
        np.save(tmp, block, allow_pickle=False)
        os.replace(tmp, path)
    except OSError:
        pass


def _block(B, FT, kinds, settings) -> np.ndarray:
    from ..kernels.bsdf import tabulated as kt
    from ..kernels.layered.iface import IF_DIST, IF_MASK, IF_P
    from ..kernels.layered.table import if_offset
    t0 = time.perf_counter()
    body = settings.get("body", False)
    mu, y, split = solve(B, FT, list(kinds), settings, 0.0 if body else None)
    n, M = mu.size, settings["M"]
    if body:
        G, H, rbar = _body_factors(B, FT, kinds, settings, y)
    else:
        G, H, rbar = np.zeros((3, n)), np.zeros((3, n)), np.zeros(3)
    o = if_offset(0)
    top = kinds[0]
    alpha = settings["top_alpha"] if top == "dielectric" else 0.0
    eta = float(B[o + IF_P]) if top == "dielectric" else 1.0
    tint = np.array(B[o + IF_P + 1:o + IF_P + 4]) if top == "dielectric" else np.ones(3)
    dist, masking = int(B[o + IF_DIST]), int(B[o + IF_MASK])
    cells = S_O * S_B
    head = np.zeros(kt.HEAD)
    packed, yoff, ycnt = _pack(y)
    parts = [mu, packed, yoff, ycnt, np.zeros(S_I * (cells + 1)), np.zeros(3 * S_I), np.zeros(S_I),
             G.ravel(), H.ravel(), rbar, np.zeros(3 * S_I)]
    offsets = np.cumsum([kt.HEAD] + [p.size for p in parts[:-1]])
    head[kt.H_BODY] = 1.0 if body else 0.0
    head[kt.H_N], head[kt.H_M] = n, M
    head[kt.H_MODE] = kt.ROUGH_TOP if settings["rough_top"] else kt.SMOOTH_TOP
    head[kt.H_ETA], head[kt.H_ALPHA], head[kt.H_DIST], head[kt.H_MASK] = eta, alpha, dist, masking
    head[kt.H_TINT:kt.H_TINT + 3] = tint
    head[kt.H_SI], head[kt.H_SO], head[kt.H_SB] = S_I, S_O, S_B
    head[kt.H_F1] = kt.NO_FIRST
    if split:
        from ..kernels.layered.table import M_TAU, md_offset
        o1 = if_offset(1)
        head[kt.H_F1] = {"diffuse": kt.FIRST_DIFFUSE, "conductor": kt.FIRST_CONDUCTOR,
                         "dielectric": kt.FIRST_DIELECTRIC}[kinds[1]]
        head[kt.H_F1_DIST], head[kt.H_F1_MASK] = B[o1 + IF_DIST], B[o1 + IF_MASK]
        head[kt.H_F1_P:kt.H_F1_P + 12] = B[o1 + IF_P:o1 + IF_P + 12]
        head[kt.H_TAU0:kt.H_TAU0 + 3] = B[md_offset(0) + M_TAU:md_offset(0) + M_TAU + 3]
    for h, off in zip((kt.H_MU, kt.H_Y, kt.H_YOFF, kt.H_YCNT, kt.H_CDF, kt.H_ALB, kt.H_RS,
                       kt.H_G, kt.H_H, kt.H_RBAR, kt.H_KBODY), offsets):
        head[h] = off
    block = np.concatenate([head] + parts)
    _sampling_tables(block, kt)
    theta = np.linspace(0.0, 0.5 * math.pi, S_I)
    mu_s = np.maximum(np.cos(theta), 1e-3)
    block[int(head[kt.H_RS]):int(head[kt.H_RS]) + S_I] = _top_reflection(B, o, top, alpha, dist, masking, mu_s)
    block.setflags(write=False)
    from .. import stats
    stats.add("layered_tables_built", 1)
    stats.add("layered_table_seconds", time.perf_counter() - t0)
    stats.add("layered_table_bytes", block.nbytes)
    return block


def _body_factors(B, FT, kinds, settings, y0):
    """A textured diffuse body of albedo ρ adds to the black-bodied table, in its order 0,
    ρ·G(μ1)·H(μ2)/(1 − ρ·r̄) per channel: the body re-emits uniformly whatever reaches it, so its
    light is rank one in (μ1, μ2), and what the stack above sends back to it is one number r̄ (the
    discretised stack has exactly this form: a Lambertian reflector's matrix is rank one, the
    Sherman–Morrison identity does the rest). G, H (3, n) and r̄ (3,) from the order 0 of two more
    solves, with albedos 1 and ½: D(ρ) = ρ P/(1 − ρ r̄), so D(1)/D(½) = 2(1 − ½r̄)/(1 − r̄)."""
    one = dict(settings, M=1)
    y1 = solve(B, FT, list(kinds), one, 1.0)[1][:, :, 0, :] - y0[:, :, 0, :]
    yh = solve(B, FT, list(kinds), one, 0.5)[1][:, :, 0, :] - y0[:, :, 0, :]
    n = y0.shape[0]
    G, H, rbar = np.zeros((3, n)), np.zeros((3, n)), np.zeros(3)
    for c in range(3):
        d1, dh = y1[:, :, c], yh[:, :, c]
        j, i = np.unravel_index(np.argmax(np.abs(d1)), d1.shape)
        if not abs(dh[j, i]) > 0.0:
            continue
        q = d1[j, i] / dh[j, i]
        rbar[c] = (2.0 - q) / (1.0 - q) if q != 1.0 else 0.0
        P = d1 * (1.0 - rbar[c])
        G[c] = P[:, i]
        H[c] = P[j, :] / P[j, i]
    return G, H, rbar


def _pack(y: np.ndarray):
    """(coefficients, offsets, counts) of y (n, n, M, 3) packed per node pair: a pair keeps its
    orders up to the last one above TRUNCATE of its own order 0 and above TRUNCATE/10 of the
    table's largest coefficient (the rest add below that to the series)."""
    n, _, M, _ = y.shape
    mag = np.abs(y).max(axis=3)
    keep = (mag > TRUNCATE * mag[:, :, :1]) & (mag > 0.1 * TRUNCATE * mag.max())
    count = np.where(keep.any(axis=2), M - np.argmax(keep[:, :, ::-1], axis=2), 0).reshape(-1)
    offsets = np.concatenate([[0], np.cumsum(3 * count)[:-1]])
    flat = y.reshape(n * n, M * 3)
    packed = np.concatenate([flat[k, :3 * c] for k, c in enumerate(count)]) if count.sum() else np.zeros(1)
    return packed, offsets.astype(np.float64), count.astype(np.float64)


def _sampling_tables(block: np.ndarray, kt) -> None:
    """The table part's sampler (kernels/bsdf/tabulated.py): per sampling node the table part
    integrated over each cell (2 × 2 points a cell), a 2 % uniform floor (every direction the
    table reaches stays possible), running sums; and the table part's albedo per channel."""
    head = block
    cells = S_O * S_B
    theta_i = np.linspace(0.0, 0.5 * math.pi, S_I)
    sub = (np.arange(2) + 0.5) / 2
    th_edges = np.linspace(0.0, 0.5 * math.pi, S_O + 1)
    # sub-points of each cell: θ uniform in cos θ, Δ uniform
    c_hi, c_lo = np.cos(th_edges[:-1]), np.cos(th_edges[1:])
    mu_o = (c_hi[:, None] + (c_lo - c_hi)[:, None] * sub[None, :]).reshape(-1)          # (S_O·2,)
    d = ((np.arange(S_B)[:, None] + sub[None, :]) * math.pi / S_B).reshape(-1)            # (S_B·2,)
    omega = (c_hi - c_lo)[:, None] * np.full(S_B, 2.0 * math.pi / S_B)[None, :]          # (S_O, S_B)
    cdf_at, alb_at, k_at = int(head[kt.H_CDF]), int(head[kt.H_ALB]), int(head[kt.H_KBODY])
    body = head[kt.H_BODY] > 0.0
    for k, th in enumerate(theta_i):
        mi = max(math.cos(th), 1e-3)
        wi = np.array([math.sqrt(1.0 - mi * mi), 0.0, mi])
        so = np.sqrt(np.maximum(1.0 - mu_o ** 2, 0.0))
        # the incident light travels along −wi (azimuth π); wo at azimuth π + Δ
        az = math.pi + d
        wo = np.stack([so[:, None] * np.cos(az)[None, :], so[:, None] * np.sin(az)[None, :],
                       np.broadcast_to(mu_o[:, None], (mu_o.size, d.size))], axis=-1).reshape(-1, 3)
        wis = np.ascontiguousarray(np.broadcast_to(wi, wo.shape))
        wo = np.ascontiguousarray(wo)
        out = np.empty((wo.shape[0], 3))
        # a textured body: the sampler follows a white one, the albedo keeps the black-bodied
        # part and the white body's addition apart (kernels/bsdf/tabulated.py ``_table_albedo``)
        kt.eval_table_part(block, 0, np.ones(3), wis, wo, out)
        v = out.reshape(S_O, 2, S_B, 2, 3).mean(axis=(1, 3))                             # (S_O, S_B, 3)
        integral = v * omega[:, :, None]
        alb = integral.sum(axis=(0, 1))
        if body:
            kt.eval_table_part(block, 0, np.zeros(3), wis, wo, out)
            black = (out.reshape(S_O, 2, S_B, 2, 3).mean(axis=(1, 3)) * omega[:, :, None]).sum(axis=(0, 1))
            block[k_at + 3 * k:k_at + 3 * k + 3] = alb - black
            alb = black
        block[alb_at + 3 * k:alb_at + 3 * k + 3] = alb
        p = integral.mean(axis=2).reshape(-1)
        total = p.sum()
        uniform = (omega / (2.0 * math.pi)).reshape(-1)
        p = 0.98 * p / total + 0.02 * uniform if total > 0.0 else uniform
        cdf = np.concatenate([[0.0], np.cumsum(p)])
        cdf /= cdf[-1]
        block[cdf_at + k * (cells + 1):cdf_at + (k + 1) * (cells + 1)] = cdf
