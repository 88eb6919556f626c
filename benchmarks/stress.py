"""Numerical stress sweep: BSDF, phase-function, medium and render queries at extreme parameters.

    python -m benchmarks.stress [--fast] [--family conductor] [--lanes 4000] [--markdown]

Every case is data (a material / phase / medium dict in the scene format, parsed by the real
loader), queried over arrays of lanes at incidence cosines down to 1e-6 (both sides for
transmissive BSDFs). Counted per case:

* ``nan``    — NaN/Inf in any output (sampled direction, weight, pdf, eval, free-flight weight,
               pixel) and the renderer's own NaN counters (samples dropped, paths killed);
* ``neg``    — negative weights, eval values, pdfs or pixels;
* ``gain``   — energy gain: an albedo estimate (R+T, per incidence and channel) above 1 by more
               than 3 standard errors, *confirmed* by a fresh run with 4× the lanes and another
               seed (with hundreds of 3σ tests a lossless case would otherwise fail by chance
               about once per 750 tests). Two independent estimators: the mean sample weight in
               IMPORTANCE mode (physical flow, no 1/η² factor) and the eval integral
               ∫ f |cos| dω by cosine-weighted sampling of both hemispheres. Phase functions:
               ∫ p dω from samples and from uniform-sphere eval. Renders: a white furnace
               (world radiance 1) must not get brighter than 1 anywhere on average;
* ``cap``    — layered random-walk cap hits (reported, must stay a small fraction of walks);
* time per lane per query (sample / eval / pdf) in microseconds.

Failures are nan + neg + gain; every count must be 0. Cases whose type has not landed (e.g. the
layered material) are listed as "n/a" with the loader's message.
"""
from __future__ import annotations

import argparse
import copy
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

COS_LIST = (1e-6, 1e-4, 1e-2, 0.3, 0.7, 1.0)
FAST_COS = (1e-6, 0.3, 1.0)


@dataclass
class Case:
    family: str          # material | layered | phase | medium | texture | render
    name: str
    spec: dict
    energy: bool = True  # physically R + T <= 1: check for energy gain
    fast: bool = False   # part of the fast subset (tests/test_stress_fast.py)
    cost: float = 1.0    # lanes are divided by this (expensive layered walks)


@dataclass
class Result:
    case: Case
    lanes: int = 0
    nan: int = 0
    neg: int = 0
    gain: int = 0
    gain_unconfirmed: int = 0
    cap: int = 0
    walks: int = 0
    max_albedo: float = 0.0      # largest albedo estimate from sample weights (or furnace pixel mean)
    max_z: float = -math.inf     # largest (estimate − 1)/se seen
    us: dict = field(default_factory=dict)       # query -> (seconds, lanes)
    seconds: float = 0.0
    warnings: int = 0
    note: str = ""
    available: bool = True

    @property
    def failures(self) -> int:
        return self.nan + self.neg + self.gain


# --------------------------------------------------------------------------- case lists

def _mf(kind, alpha, alpha_v=None, dist="ggx", masking="height-correlated", **kw):
    d = {"type": kind, "roughness": alpha, "distribution": dist, "masking": masking, **kw}
    if alpha_v is not None:
        d["roughness_v"] = alpha_v
    return d


def material_cases() -> list[Case]:
    cases = []
    for a in (0.0, 1e-4, 1e-3, 0.05, 0.5, 1.0):
        for dist in ("ggx", "beckmann"):
            fast = dist == "ggx" and a in (0.0, 1e-4, 1.0)
            cases.append(Case("material", f"conductor Cu α={a:g} {dist}", _mf("conductor", a, dist=dist, metal="Cu"), fast=fast))
            cases.append(Case("material", f"dielectric 1.5 α={a:g} {dist}", _mf("dielectric", a, dist=dist, ior=1.5), fast=fast))
    cases += [
        Case("material", "conductor F=1 (eta 0, k 1) α=1e-4", _mf("conductor", 1e-4, eta=[0, 0, 0], k=[1, 1, 1]), fast=True),
        Case("material", "conductor F=1 α=1 separable", _mf("conductor", 1.0, masking="separable", eta=[0, 0, 0], k=[1, 1, 1])),
        Case("material", "conductor anisotropic α 1e-4 × 1", _mf("conductor", 1e-4, 1.0, metal="Au"), fast=True),
        Case("material", "conductor eta 1e-3 k 1e-3", _mf("conductor", 0.3, eta=[1e-3] * 3, k=[1e-3] * 3)),
        Case("material", "conductor eta 50 k 50", _mf("conductor", 0.3, eta=[50] * 3, k=[50] * 3)),
        Case("material", "dielectric anisotropic α 1e-4 × 1", _mf("dielectric", 1e-4, 1.0, ior=1.5), fast=True),
        Case("material", "diffuse albedo 0", {"type": "diffuse", "color": [0, 0, 0]}),
        Case("material", "diffuse albedo exactly 1", {"type": "diffuse", "color": [1, 1, 1]}, fast=True),
    ]
    for ior in (1.0001, 1.01, 1.33, 3.0):
        for a in (0.0, 1e-4, 0.3):
            cases.append(Case("material", f"dielectric ior {ior:g} α={a:g}", _mf("dielectric", a, ior=ior),
                              fast=(ior == 1.0001 and a != 0.3)))
    cases += [
        Case("material", "dielectric index-matched 1.5|1.5 α=0", _mf("dielectric", 0.0, ior=1.5, ior_above=1.5), fast=True),
        Case("material", "dielectric index-matched 1.5|1.5 α=0.3", _mf("dielectric", 0.3, ior=1.5, ior_above=1.5)),
        Case("material", "dielectric inverted 1.5→1.0 α=0.1", _mf("dielectric", 0.1, ior=1.0, ior_above=1.5)),
        Case("material", "dielectric ior 3 α=1 beckmann separable", _mf("dielectric", 1.0, dist="beckmann", masking="separable", ior=3.0)),
    ]
    return cases


def _slab(sigma_t=1.0, albedo=0.9, phase=None, thickness=1.0):
    return {"thickness": thickness, "sigma_t": sigma_t, "albedo": albedo, "phase": phase or {"type": "isotropic"}}


def _coat(ior=1.5, a=0.1, **kw):
    return _mf("dielectric", a, ior=ior, **kw)


def layered_cases() -> list[Case]:
    from .scenes import validation_stack
    L = []
    for k in (1, 2, 3, 4):
        L.append(Case("layered", f"validation {k}", validation_stack(k), fast=k in (1, 4)))
    cu = _mf("conductor", 0.05, metal="Cu")
    white = {"type": "diffuse", "color": [1, 1, 1]}

    def stack(ifaces, media, **opt):
        return {"type": "layered", "interfaces": ifaces, "media": media, **opt}
    for a in (1e-4, 1.0):
        L.append(Case("layered", f"coat α={a:g} / slab / Cu", stack([_coat(a=a), cu], [_slab()]), fast=a == 1e-4))
    for ior in (1.0001, 3.0):
        L.append(Case("layered", f"coat ior {ior:g} / slab / Cu", stack([_coat(ior=ior), cu], [_slab()]), fast=ior == 1.0001))
    L.append(Case("layered", "index-matched coat over coat (1.5|1.5)",
                  stack([_coat(1.5, 0.1), _coat(1.5, 0.2), cu], [_slab(), _slab()]), fast=True))
    L.append(Case("layered", "null interface between slabs", stack([_coat(), {"type": "null"}, cu], [_slab(), _slab()])))
    for tau in (0.0, 1e-3, 1e3):
        L.append(Case("layered", f"optical depth {tau:g}", stack([_coat(), cu], [_slab(sigma_t=tau)]), fast=tau in (0.0, 1e3)))
    L.append(Case("layered", "albedo 0 medium", stack([_coat(), cu], [_slab(albedo=0.0)])))
    L.append(Case("layered", "lossless: coat / albedo-1 slab / white diffuse",
                  stack([_coat(a=0.1), white], [_slab(sigma_t=2.0, albedo=1.0)]), fast=True))
    L.append(Case("layered", "lossless thick: albedo 1, τ 1e3, white diffuse",
                  stack([_coat(a=0.1), white], [_slab(sigma_t=1e3, albedo=1.0)])))
    for g in (-0.999, 0.999):
        L.append(Case("layered", f"HG g={g:+g}", stack([_coat(), cu], [_slab(phase={"type": "hg", "g": g})]), fast=g > 0))
    for s in (1e-3, 4.0):
        L.append(Case("layered", f"microflake stddev {s:g}",
                      stack([_coat(), cu], [_slab(phase={"type": "microflake", "stddev": s, "orientation": [1, 0, 0]})])))
    L.append(Case("layered", "fibers parallel to the normal (stddev 0.05)",
                  stack([_coat(), cu], [_slab(phase={"type": "microflake", "stddev": 0.05, "orientation": [0, 0, 1]})]),
                  fast=True))
    L.append(Case("layered", "fibers ∥ normal, stddev 1e-3, albedo 1",
                  stack([_coat(), white], [_slab(albedo=1.0, phase={"type": "microflake", "stddev": 1e-3, "orientation": [0, 0, 1]})])))
    # Transmissive stacks (bottom dielectric): both sides.
    L.append(Case("layered", "transmissive: coat / slab / dielectric",
                  stack([_coat(1.5, 0.1), _coat(1.0, 0.1)], [_slab(albedo=0.95, phase={"type": "hg", "g": 0.8})]), fast=True))
    L.append(Case("layered", "transmissive index-matched throughout",
                  stack([_coat(1.0001, 0.0), _coat(1.0, 0.0)], [_slab(sigma_t=0.5, albedo=1.0)])))
    # 16 interfaces: 15 rough coats of alternating index over copper, 15 slabs.
    ifaces = [_coat(1.3 if i % 2 else 1.6, 0.1) for i in range(15)] + [cu]
    media = [_slab(sigma_t=0.3, albedo=0.95, phase={"type": "hg", "g": 0.3}) for _ in range(15)]
    L.append(Case("layered", "16-layer stack", stack(ifaces, media), fast=True, cost=8.0))
    for est, pdf in (("uni", "approx"), ("bi", "stochastic")):
        L.append(Case("layered", f"validation 1 estimator {est} pdf {pdf}",
                      {**validation_stack(1), "estimator": est, "pdf": pdf}, fast=est == "uni"))
    return L


def phase_cases() -> list[Case]:
    P = [Case("phase", "isotropic", {"type": "isotropic"})]
    for g in (-1.0, -0.999, 0.0, 0.999, 1.0):
        P.append(Case("phase", f"HG g={g:+g}", {"type": "hg", "g": g}, fast=abs(g) >= 0.999))
    for kappa in (0.0, 1e-8, 1e3, 1e7):
        P.append(Case("phase", f"vMF κ={kappa:g}", {"type": "vmf", "kappa": kappa}, fast=kappa in (0.0, 1e7)))
    for s in (1e-4, 1e-3, 0.05, 4.0):
        for o, oname in (([1, 0, 0], "in-plane"), ([0, 0, 1], "∥ normal")):
            P.append(Case("phase", f"microflake stddev {s:g} fibers {oname}",
                          {"type": "microflake", "stddev": s, "orientation": o}, fast=s in (1e-4, 4.0)))
    for r in (1e-3, 1.0):
        P.append(Case("phase", f"SGGX fiber roughness {r:g} ∥ normal", {"type": "sggx", "shape": "fiber", "roughness": r,
                                                                      "orientation": [0, 0, 1]}, fast=r == 1e-3))
        P.append(Case("phase", f"SGGX flake roughness {r:g}", {"type": "sggx", "shape": "flake", "roughness": r}))
    return P


def medium_cases() -> list[Case]:
    M = []
    for tau in (0.0, 1e-6, 1.0, 1e3):
        for alb in (0.0, 1.0):
            M.append(Case("medium", f"τ={tau:g} albedo {alb:g}", _slab(sigma_t=tau, albedo=alb), fast=tau in (0.0, 1e3)))
    M.append(Case("medium", "chromatic σt (1e-3, 1, 1e3)", _slab(sigma_t=[1e-3, 1.0, 1e3], albedo=[0.0, 0.5, 1.0]), fast=True))
    M.append(Case("medium", "microflake fibers ∥ normal, τ 1e3",
                  _slab(sigma_t=1e3, phase={"type": "microflake", "stddev": 1e-3, "orientation": [0, 0, 1]}), fast=True))
    M.append(Case("medium", "thickness 0", _slab(thickness=0.0, sigma_t=5.0)))
    return M


def texture_cases(tex: Path) -> list[Case]:
    t = str(tex)
    huge = str(tex.with_name(tex.stem + "_huge" + tex.suffix))
    T = [Case("texture", "diffuse colour texture (NaN/−/Inf texels)", {"type": "diffuse", "color": {"texture": t}}, fast=True),
         Case("texture", "diffuse colour texture with 1e30 texels (NaN/neg only)", {"type": "diffuse", "color": {"texture": huge}},
              energy=False),
         Case("texture", "conductor roughness texture", _mf("conductor", {"texture": t, "channel": 0}, metal="Cu"), fast=True),
         Case("texture", "conductor eta/k textures", _mf("conductor", 0.2, eta={"texture": t}, k={"texture": t})),
         Case("texture", "dielectric roughness + ior texture",
              _mf("dielectric", {"texture": t, "channel": 1}, ior={"texture": t, "channel": 2}), fast=True)]
    T.append(Case("texture", "layered: textured coat roughness, σt, albedo, g, orientation", {
        "type": "layered", "interfaces": [_coat(a={"texture": t, "channel": 0}), _mf("conductor", 0.1, metal="Cu")],
        "media": [{"thickness": {"texture": t, "channel": 2}, "sigma_t": {"texture": t, "channel": 1},
                   "albedo": {"texture": t}, "phase": {"type": "hg", "g": {"texture": t, "channel": 0}}}]}, fast=True))
    T.append(Case("texture", "layered: textured microflake orientation", {
        "type": "layered", "interfaces": [_coat(), _mf("conductor", 0.1, metal="Cu")],
        "media": [{"sigma_t": 1.0, "albedo": 0.9,
                   "phase": {"type": "microflake", "stddev": 0.05, "orientation": {"texture": t}}}]}))
    return T


def render_cases(tex: Path) -> list[Case]:
    """Furnace renders (sphere in a constant world of radiance 1): the sphere must not be brighter."""
    from .scenes import validation_stack
    R = [Case("render", "conductor F=1 α=1e-4", _mf("conductor", 1e-4, eta=[0, 0, 0], k=[1, 1, 1]), fast=True),
         Case("render", "smooth glass ior 1.0001", _mf("dielectric", 0.0, ior=1.0001), fast=True),
         Case("render", "rough glass ior 3 α 1", _mf("dielectric", 1.0, ior=3.0)),
         Case("render", "diffuse albedo 1", {"type": "diffuse", "color": [1, 1, 1]}),
         Case("render", "textured diffuse (NaN/−/Inf texels)", {"type": "diffuse", "color": {"texture": str(tex)}}, fast=True),
         Case("render", "layered validation 4", validation_stack(4), fast=True),
         Case("render", "layered lossless coat/slab/white", {
             "type": "layered", "interfaces": [_coat(a=0.1), {"type": "diffuse", "color": [1, 1, 1]}],
             "media": [_slab(sigma_t=2.0, albedo=1.0)]})]
    return R


def all_cases(tex: Path) -> list[Case]:
    cases = material_cases() + layered_cases() + phase_cases() + medium_cases() + texture_cases(tex) + render_cases(tex)
    for c in cases:
        if c.spec.get("type") == "layered" and c.cost == 1.0:
            c.cost = 4.0   # a layered query is ~100-1000× an analytic one
    return cases


def write_texture(path: Path, huge: bool = False) -> Path:
    """A 4×4 float EXR with NaN, ±Inf, negative, tiny and ordinary [0, 1] texels in every channel
    (``huge``: 1e30 and values above 1 as well — legal for colours, which may exceed 1 as in
    Blender, so such a texture is only checked for NaN/negative output, not for energy)."""
    import OpenImageIO as oiio
    vals = np.array([np.nan, -1.0, np.inf, -np.inf, 1.0, 0.0, 0.25, 0.5, 1.0, 0.9, -1e-30, 0.75, np.nan, 0.1, 1e-30, -0.5])
    if huge:
        vals[[4, 9, 14]] = (1e30, 2.0, 3.0)
    pix = np.stack([vals, np.roll(vals, 5), np.roll(vals, 11)], axis=-1).reshape(4, 4, 3).astype(np.float32)
    path.parent.mkdir(parents=True, exist_ok=True)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(4, 4, 3, oiio.FLOAT))
    out.write_image(pix)
    out.close()
    return path


# --------------------------------------------------------------------------- building

def _ctx(base: Path):
    from backend.scene.reader import LoadContext
    ctx = LoadContext("<stress>", base)
    ctx.cache["layered_defaults"] = {}
    return ctx


def build(case: Case, base: Path):
    """(object, load context) for a case; raises LaminaError if its type has not landed."""
    from backend.scene.reader import Node, dispatch
    ctx = _ctx(base)
    node = Node(copy.deepcopy(case.spec), "", ctx)
    if case.family in ("material", "layered", "texture", "render"):
        from backend.materials import load_all
        return dispatch(node, load_all()), ctx
    if case.family == "phase":
        from backend.layered.phase import parse_phase
        return parse_phase(node), ctx
    if case.family == "medium":
        from backend.layered.medium import parse_medium
        return parse_medium(node), ctx
    raise ValueError(case.family)


# --------------------------------------------------------------------------- checks

def _bad(a) -> tuple[int, int]:
    a = np.asarray(a, dtype=np.float64)
    fin = np.isfinite(a)
    return int((~fin).sum()), int((a[fin] < 0).sum())


def _dirs(cos_t: float, n: int, rng, sign: float = 1.0) -> np.ndarray:
    phi = rng.random(n) * 2 * np.pi
    s = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    return np.stack([s * np.cos(phi), s * np.sin(phi), np.full(n, sign * cos_t)], axis=1)


def _cosine_both(n: int, rng, both: bool) -> tuple[np.ndarray, np.ndarray]:
    """Cosine-weighted directions over the upper (or both) hemispheres and their pdf."""
    u = rng.random((n, 2))
    r = np.sqrt(u[:, 0])
    phi = 2 * np.pi * u[:, 1]
    z = np.sqrt(np.maximum(0.0, 1.0 - u[:, 0]))
    z = np.maximum(z, 1e-300)
    sign = np.where(rng.random(n) < 0.5, -1.0, 1.0) if both else np.ones(n)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), sign * z], axis=1)
    pdf = z / np.pi * (0.5 if both else 1.0)
    return d, pdf


class Energy:
    """Collects albedo estimates: mean ± standard error per channel; flags mean − 1 > 3 se."""

    def __init__(self):
        self.flags = []      # (key, z) of 3σ exceedances
        self.max_mean = 0.0
        self.max_z = -math.inf

    def add(self, key, values: np.ndarray) -> None:
        v = np.asarray(values, dtype=np.float64)
        v = np.where(np.isfinite(v), v, 0.0)   # non-finite values are counted separately
        n = v.shape[0]
        mean = v.mean(axis=0)
        se = v.std(axis=0, ddof=1) / math.sqrt(n) if n > 1 else np.zeros_like(mean)
        z = (mean - 1.0) / np.maximum(se, 1e-300)
        if key[-1] != "eval":   # the eval integral of sharp lobes is too noisy to be informative here
            self.max_mean = max(self.max_mean, float(np.max(mean)))
        self.max_z = max(self.max_z, float(np.max(np.where(se > 0, z, np.where(mean > 1 + 1e-9, np.inf, -np.inf)))))
        # 1e-9: rounding of weights that are exactly 1 (e.g. a white diffuse surface).
        hit = mean - 1.0 > 3.0 * se + 1e-9
        for c in np.flatnonzero(np.atleast_1d(hit)):
            self.flags.append((key, int(c)))


def _timed(us: dict, key: str, lanes: int, f):
    """Run f(); accumulate its time and lane count under ``key`` (µs per lane = t / n)."""
    t0 = time.perf_counter()
    out = f()
    t, n = us.get(key, (0.0, 0))
    us[key] = (t + time.perf_counter() - t0, n + lanes)
    return out


def query_bsdf(material, lanes: int, cos_list, seed: int, res: Result, energy: Energy) -> None:
    from backend.materials.base import IMPORTANCE, RADIANCE, ShadingContext
    rng = np.random.default_rng(seed)
    uv = rng.random((lanes, 2))
    bsdf = material.bind(ShadingContext(uv))
    transmissive = bool(getattr(bsdf, "transmissive", False))
    signs = (1.0, -1.0) if transmissive else (1.0,)
    ncos = len(cos_list) * len(signs)
    for sign in signs:
        for c in cos_list:
            wi = _dirs(c, lanes, rng, sign)
            key = (sign * c,)
            s = _timed(res.us, "sample", lanes, lambda: bsdf.sample(wi, rng, IMPORTANCE))
            for arr in (s.wo, s.weight, s.pdf):
                nan, neg = _bad(arr)
                res.nan += nan
                res.neg += neg if arr is not s.wo else 0
            alive = np.all(np.isfinite(s.weight), axis=1) & (s.weight.max(axis=1) > 0)
            not_unit = int(np.sum(np.abs(np.linalg.norm(s.wo[alive], axis=1) - 1) > 1e-6))
            if not_unit:
                res.nan += not_unit
                res.note = "sampled direction not unit"
            energy.add(key + ("sample",), s.weight)
            wo, p = _cosine_both(lanes, rng, transmissive)
            f = _timed(res.us, "eval", lanes, lambda: bsdf.eval(wi, wo, rng, RADIANCE))
            fi = _timed(res.us, "eval", lanes, lambda: bsdf.eval(wi, wo, rng, IMPORTANCE))
            pd = _timed(res.us, "pdf", lanes, lambda: bsdf.pdf(wi, wo, rng, RADIANCE))
            for arr in (f, fi, pd):
                nan, neg = _bad(arr)
                res.nan += nan
                res.neg += neg
            energy.add(key + ("eval",), fi / p[:, None])
    res.lanes += lanes * ncos


def query_phase(spec, lanes: int, cos_list, seed: int, res: Result, energy: Energy) -> None:
    rng = np.random.default_rng(seed)
    phase = spec.bind(rng.random((lanes, 2)))
    for c in cos_list:
        for sign in (1.0, -1.0):
            d_in = _dirs(c, lanes, rng, sign)
            key = (sign * c,)
            s = _timed(res.us, "sample", lanes, lambda: phase.sample(d_in, rng))
            for arr in (s.d_out, s.weight, s.pdf):
                nan, neg = _bad(arr)
                res.nan += nan
                res.neg += neg if arr is not s.d_out else 0
            energy.add(key + ("sample",), s.weight[:, None])
            # Uniform sphere directions (pdf 1/4π) for the eval integral.
            z = rng.random(lanes) * 2 - 1
            d_out = _dirs(0.0, lanes, rng)
            d_out[:, :2] *= np.sqrt(np.maximum(0.0, 1 - z * z))[:, None]
            d_out[:, 2] = z
            e = _timed(res.us, "eval", lanes, lambda: phase.eval(d_in, d_out))
            pd = phase.pdf(d_in, d_out)
            sig = phase.sigma_scale(d_in)
            for arr in (e, pd, sig):
                nan, neg = _bad(arr)
                res.nan += nan
                res.neg += neg
            energy.add(key + ("eval",), (4 * np.pi * e)[:, None])
    res.lanes += lanes * len(cos_list) * 2


def query_medium(spec, lanes: int, cos_list, seed: int, res: Result, energy: Energy) -> None:
    rng = np.random.default_rng(seed)
    med = spec.bind(rng.random((lanes, 2)))
    for c in cos_list:
        for sign in (1.0, -1.0):
            d = _dirs(c, lanes, rng, sign)
            key = (sign * c,)
            depth = rng.random(lanes)
            ff = _timed(res.us, "sample", lanes, lambda: med.free_flight(depth, d, rng))
            tr = med.transmittance(d)
            for arr in (ff.depth, ff.weight, ff.pdf, tr):
                nan, neg = _bad(arr)
                res.nan += nan
                res.neg += neg
            out_of_slab = int(np.sum((ff.depth < 0) | (ff.depth > 1)))
            if out_of_slab:
                res.nan += out_of_slab
                res.note = "free-flight depth outside [0, 1]"
            # One free-flight step: E[weight_k] = albedo_k (1 − T_k) + T_k <= 1 (scatter or pass).
            energy.add(key + ("flight",), ff.weight)
            trf = np.where(np.isfinite(tr), tr, 0)
            if np.any(trf > 1 + 1e-12):
                res.gain += int(np.sum(trf > 1 + 1e-12))
                res.note = "transmittance > 1"
    res.lanes += lanes * len(cos_list) * 2


def query_render(material_spec: dict, size: int, spp: int, seed: int, res: Result, energy: Energy, base: Path) -> None:
    """White furnace: a sphere with the material in a constant world of radiance 1."""
    from backend.render import Renderer, RenderOptions
    from backend.scene.loader import load_scene_data
    from .scenes import perspective
    data = {"format": "lamina-scene", "version": 1, "film": {"width": size, "height": size},
            "camera": perspective((0, -4, 0), (0, 0, 0), 30.0, size, size),
            "render": {"spp": spp, "max_bounces": 32, "seed": seed},
            "materials": {"m": material_spec}, "meshes": {"ball": {"shape": "sphere", "radius": 1.0, "segments": 64}},
            "objects": [{"name": "ball", "mesh": "ball", "materials": ["m"]}], "lights": [],
            "world": {"type": "constant", "color": [1, 1, 1], "strength": 1.0}}
    scene = load_scene_data(copy.deepcopy(data), "<stress furnace>", base)
    res.warnings += len(scene.warnings)
    opts = RenderOptions(workers=1)
    t0 = time.perf_counter()
    r = Renderer(scene, (data, "<stress furnace>", str(base)), opts).run()
    t, n = res.us.get("render", (0.0, 0))
    res.us["render"] = (t + time.perf_counter() - t0, n + size * size * spp)
    img = r.film.combined()
    nan, neg = _bad(img)
    res.nan += nan + int(r.stats.get("samples_nonfinite_dropped", 0)) + int(r.stats.get("paths_nonfinite_killed", 0))
    res.neg += neg
    res.cap += int(r.stats.get("layered_walk_cap_hits", 0))
    res.lanes += size * size * spp
    # Pixel means are independent: test the whole image mean (the furnace value is 1 everywhere).
    v = r.film.variance_of_mean()
    mean = img.reshape(-1, 3).mean(axis=0)
    se = np.sqrt(v.reshape(-1, 3).sum(axis=0)) / (size * size)
    z = (mean - 1) / np.maximum(se, 1e-300)
    energy.max_mean = max(energy.max_mean, float(mean.max()))
    energy.max_z = max(energy.max_z, float(z.max()))
    for ch in np.flatnonzero(mean - 1 > 3 * se + 1e-9):
        energy.flags.append((("image",), int(ch)))


# --------------------------------------------------------------------------- running

def _layered_stats(obj) -> dict:
    st = getattr(obj, "stats", None)
    return st if isinstance(st, dict) else {}


def run_case(case: Case, base: Path, lanes: int, fast: bool, seed: int = 1) -> Result:
    from backend import stats as global_stats
    from backend.errors import LaminaError
    res = Result(case)
    cos_list = FAST_COS if fast else COS_LIST
    try:
        obj, ctx = build(case, base)
    except LaminaError as exc:
        res.available = False
        res.note = str(exc)
        return res
    except ImportError as exc:
        res.available = False
        res.note = f"not available: {exc}"
        return res
    res.warnings = len(ctx.warnings)
    global_stats.take()

    def one(lanes_, seed_, energy):
        if case.family in ("material", "layered", "texture"):
            query_bsdf(obj, lanes_, cos_list, seed_, res, energy)
        elif case.family == "phase":
            query_phase(obj, lanes_, cos_list, seed_, res, energy)
        elif case.family == "medium":
            query_medium(obj, lanes_, cos_list, seed_, res, energy)
        elif case.family == "render":
            size, spp = (12, 4) if fast else (24, 16)
            query_render(case.spec, size * (2 if lanes_ > lanes else 1), spp, seed_, res, energy, base)

    energy = Energy()
    one(lanes, seed, energy)
    res.max_albedo, res.max_z = energy.max_mean, energy.max_z
    if energy.flags and case.energy:
        # Confirm each 3σ exceedance with 4× the lanes and an independent seed.
        res.gain_unconfirmed = len(energy.flags)
        confirm = Energy()
        one(lanes * 4, seed + 1000, confirm)
        flagged = set(energy.flags)
        res.gain += sum(1 for f in confirm.flags if f in flagged)
        res.max_albedo = max(res.max_albedo, confirm.max_mean)
    st = _layered_stats(obj)
    if st:
        res.cap += int(st.get("cap_hits", 0))
        res.walks += int(st.get("walks", 0))
    else:
        res.cap += int(global_stats.take().get("layered_walk_cap_hits", 0))
    return res


def lanes_for(case: Case, lanes: int) -> int:
    return max(64, int(lanes / case.cost))


def run(fast: bool = False, families=None, lanes: int | None = None, base: Path | None = None,
        log=None, select=None) -> list[Result]:
    base = Path(base) if base is not None else Path(__file__).resolve().parent / ".cache"
    tex = write_texture(base / "stress_texels.exr")
    write_texture(base / "stress_texels_huge.exr", huge=True)
    lanes = lanes or (256 if fast else 4000)
    out = []
    for case in all_cases(tex):
        if families and case.family not in families:
            continue
        if fast and not case.fast:
            continue
        if select and not select(case):
            continue
        t0 = time.perf_counter()
        res = run_case(case, base, lanes_for(case, lanes), fast)
        res.seconds = time.perf_counter() - t0
        if log:
            log(format_row(res))
        out.append(res)
    return out


# --------------------------------------------------------------------------- output

HEAD = ("family", "case", "lanes", "NaN/Inf", "negative", "energy gain", "3σ flags (unconfirmed)",
        "max albedo", "max z", "walk-cap hits", "µs/lane sample", "µs/lane eval", "µs/lane pdf", "note")


def _us(r: Result, k: str) -> str:
    if k not in r.us or not r.us[k][1]:
        return "–"
    v = r.us[k][0] * 1e6 / r.us[k][1]
    return f"{v:.2f}" if v < 100 else f"{v:.0f}"


def _z(z: float) -> str:
    if not math.isfinite(z):
        return "–"
    return "< −99" if z < -99 else "> 99" if z > 99 else f"{z:+.1f}"


def row_values(r: Result) -> tuple:
    if not r.available:
        return (r.case.family, r.case.name, "–", "n/a", "n/a", "n/a", "", "", "", "", "", "", "", r.note)
    cap = f"{r.cap}" + (f" / {r.walks} walks" if r.walks else "")
    sample_key = "render" if r.case.family == "render" else "sample"
    note = r.note + (f" ({r.warnings} load warnings)" if r.warnings else "")
    gain = str(r.gain) if r.case.energy else "not checked"
    return (r.case.family, r.case.name, str(r.lanes), str(r.nan), str(r.neg), gain, str(r.gain_unconfirmed),
            f"{r.max_albedo:.4f}" if r.max_albedo < 1e4 else f"{r.max_albedo:.3g}", _z(r.max_z), cap, _us(r, sample_key), _us(r, "eval"), _us(r, "pdf"), note.strip())


def format_row(r: Result) -> str:
    v = row_values(r)
    return f"{v[0]:8s} {v[1][:52]:52s} {v[2]:>8s} nan {v[3]:>4s} neg {v[4]:>4s} gain {v[5]:>3s} ({v[6]:>2s}) " \
           f"alb {v[7]:>7s} z {v[8]:>5s} cap {v[9]:>6s} µs {v[10]:>6s}/{v[11]:>6s}/{v[12]:>6s} {v[13]}"


def markdown(results: list[Result]) -> str:
    lines = ["| " + " | ".join(HEAD) + " |", "|" + "---|" * len(HEAD)]
    for r in results:
        lines.append("| " + " | ".join(str(x).replace("|", "\\|") for x in row_values(r)) + " |")
    return "\n".join(lines)


def totals(results: list[Result]) -> dict:
    ok = [r for r in results if r.available]
    return {"cases": len(results), "run": len(ok), "not_available": len(results) - len(ok),
            "nan": sum(r.nan for r in ok), "neg": sum(r.neg for r in ok), "gain": sum(r.gain for r in ok),
            "gain_unconfirmed": sum(r.gain_unconfirmed for r in ok), "cap": sum(r.cap for r in ok),
            "walks": sum(r.walks for r in ok)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fast", action="store_true", help="the fast subset (what tests/test_stress_fast.py runs)")
    ap.add_argument("--family", action="append", help="only these families (repeatable)")
    ap.add_argument("--lanes", type=int, help="lanes per incidence angle")
    ap.add_argument("--markdown", action="store_true", help="print a Markdown table at the end")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    print(f"{'family':8s} {'case':52s} {'lanes':>8s}")
    results = run(args.fast, args.family, args.lanes, log=lambda s: print(s, flush=True))
    tot = totals(results)
    print(f"\n{tot['run']} cases run ({tot['not_available']} not available), {time.perf_counter() - t0:.1f} s: "
          f"NaN/Inf {tot['nan']}, negative {tot['neg']}, energy gain {tot['gain']} "
          f"(3σ flags before confirmation {tot['gain_unconfirmed']}), walk-cap hits {tot['cap']}")
    if args.markdown:
        print()
        print(markdown(results))
    return 1 if tot["nan"] + tot["neg"] + tot["gain"] else 0


if __name__ == "__main__":
    sys.exit(main())
