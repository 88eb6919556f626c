"""Helpers for the layered-BSDF tests: the stacks of issue 3, loading, batched statistics."""
from __future__ import annotations

import copy

import numpy as np

from backend.materials import load_all
from backend.materials.base import IMPORTANCE, ShadingContext
from backend.scene.reader import LoadContext, Node, dispatch

# The project's reference example (issue 3), exactly as written there.
REFERENCE = {
    "type": "layered",
    "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.05, "distribution": "beckmann"},
                   {"type": "dielectric", "ior": 1.2, "roughness": 0.01},
                   {"type": "conductor", "metal": "Cu", "roughness": 0.05}],
    "media": [{"thickness": 1.0, "sigma_t": 0.5, "albedo": [0.5, 0.7, 0.95],
               "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, 0.5, 0]}},
              {"thickness": 1.0, "sigma_t": 0.5, "albedo": [0.5, 0.95, 0.5],
               "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, -0.5, 0]}}]}

# Guo et al. 2018, Fig. 2 top: dielectric 1.5 α 0.05 / HG g 0.5 σt 1 albedo (0.5, 0.7, 0.95) /
# Cu α 0.05 (Beckmann, as in the paper's scenes).
FIG2_TOP = {
    "type": "layered",
    "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.05, "distribution": "beckmann"},
                   {"type": "conductor", "metal": "Cu", "roughness": 0.05, "distribution": "beckmann"}],
    "media": [{"sigma_t": 1.0, "albedo": [0.5, 0.7, 0.95], "phase": {"type": "hg", "g": 0.5}}]}

# A transmissive two-slab stack (rough dielectrics, chromatic σt, a denser medium below: index
# 1.6 outside the bottom, so the two transport modes differ).
TRANSMISSIVE = {
    "type": "layered",
    "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.2},
                   {"type": "dielectric", "ior": 1.2, "roughness": 0.1, "roughness_v": 0.3},
                   {"type": "dielectric", "ior": 1.6, "roughness": 0.15}],
    "media": [{"sigma_t": [0.5, 1.0, 1.5], "albedo": [0.9, 0.8, 0.7], "phase": {"type": "hg", "g": 0.6}},
              {"sigma_t": 0.8, "albedo": 0.95, "phase": {"type": "hg", "g": -0.3}}]}

STACKS = {"reference": REFERENCE, "fig2-top": FIG2_TOP, "transmissive": TRANSMISSIVE}

# The reference stack as the paper evaluates multi-layer stacks with the unidirectional
# estimator: nested (interfaces 1..2 with medium 1 as the bottom interface of a one-slab stack).
REFERENCE_NESTED_UNI = {
    "type": "layered", "estimator": "uni",
    "interfaces": [REFERENCE["interfaces"][0],
                   {"type": "layered", "estimator": "uni",
                    "interfaces": REFERENCE["interfaces"][1:], "media": REFERENCE["media"][1:]}],
    "media": REFERENCE["media"][:1]}

# A stack whose sampler never loses a walk (null interface, a medium, a Lambertian base).
LOSSLESS_SAMPLER = {
    "type": "layered",
    "interfaces": [{"type": "null"}, {"type": "diffuse", "color": [0.9, 0.6, 0.3]}],
    "media": [{"sigma_t": 1.5, "albedo": [0.95, 0.8, 0.5], "phase": {"type": "hg", "g": 0.7}}]}


def load(material: dict, defaults: dict | None = None):
    """A material as a scene would load it; layered stacks with the random walk's bidirectional
    estimator unless the material or ``defaults`` say otherwise: these helpers serve the walk's
    own tests (the deterministic forms have theirs: tests/test_coated_diffuse.py,
    tests/test_tabulated.py, which pass ``{"estimator": "auto"}``)."""
    ctx = LoadContext("<test>")
    ctx.cache["layered_defaults"] = {"estimator": "bi"} if defaults is None else defaults
    return dispatch(Node(copy.deepcopy(material), "", ctx), load_all())


def bind(material, n: int, uv=None):
    uv = np.zeros((n, 2)) if uv is None else uv
    return material.bind(ShadingContext(uv))


def direction(theta_deg: float, phi_deg: float = 0.0) -> np.ndarray:
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def repeat_pairs(wi: np.ndarray, wo: np.ndarray, reps: int):
    """(P, 3) pairs → (P·reps, 3) lanes, pair-major."""
    return np.repeat(wi, reps, axis=0), np.repeat(wo, reps, axis=0)


def eval_stats(material, wi, wo, reps: int, rng, estimator=None, mode=IMPORTANCE):
    """Mean and standard error (P, 3) of ``reps`` independent estimates per pair."""
    a, b = repeat_pairs(np.asarray(wi), np.asarray(wo), reps)
    bsdf = bind(material, a.shape[0])
    f = bsdf.eval(a, b, rng, mode, estimator=estimator) if estimator else bsdf.eval(a, b, rng, mode)
    assert np.all(np.isfinite(f))
    f = f.reshape(-1, reps, 3)
    return f.mean(axis=1), f.std(axis=1, ddof=1) / np.sqrt(reps)


def uniform_sphere(rng, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


# ---------------------------------------------------------------- peak-centred cells and mixture
PSI_EDGES = np.radians([0.0, 2.0, 4.0, 8.0, 15.0, 30.0, 60.0, 100.0, 180.0])
N_AZ = 8


def peak_frames(wi1, eta_out):
    """Orthonormal frames (rows: x, y, z) around the mirror direction and around the straight
    refracted direction through the whole stack (Snell between the outside media), where the
    sharp lobes of a flat stack sit; cells are polar (angle ψ from the centre, azimuth)."""
    mirror = np.array([-wi1[0], -wi1[1], wi1[2]])
    s = np.hypot(wi1[0], wi1[1]) / eta_out
    if s < 1.0:
        refr = np.array([-wi1[0] / eta_out, -wi1[1] / eta_out, -np.sign(wi1[2]) * np.sqrt(1 - s * s)])
    else:
        refr = np.array([0.0, 0.0, -np.sign(wi1[2])])
    frames = []
    for c in (mirror, refr):
        c = c / np.linalg.norm(c)
        t = np.cross(c, [0.3, 0.5, 0.7])
        t /= np.linalg.norm(t)
        frames.append(np.stack([t, np.cross(c, t), c]))
    return frames


def cells_of(d, wi1, frames):
    side = (d[:, 2] * wi1[2] > 0).astype(int)  # 1: reflection side
    loc = np.where(side[:, None] == 1, d @ frames[0].T, d @ frames[1].T)
    psi = np.arccos(np.clip(loc[:, 2], -1, 1))
    az = np.mod(np.arctan2(loc[:, 1], loc[:, 0]), 2 * np.pi)
    i = np.clip(np.searchsorted(PSI_EDGES, psi, side="right") - 1, 0, len(PSI_EDGES) - 2)
    j = np.clip((az / (2 * np.pi) * N_AZ).astype(int), 0, N_AZ - 1)
    return (side * (len(PSI_EDGES) - 1) + i) * N_AZ + j


def mixture_directions(mat, wi1, m, rng, frames=None):
    """m directions from a defensive mixture and their density q: uniform over the exit
    directions (half) and, per peak, a ψ ring chosen with equal probability then uniform in it.
    Integrals of sharp lobes (and of slivers cut by the horizon) are then estimated by
    mean(g/q) without missing the peaks."""
    if frames is None:
        frames = peak_frames(wi1, 1.0 / mat.eta_bottom if wi1[2] < 0 else mat.eta_bottom)
    nring = len(PSI_EDGES) - 1
    sphere = mat.transmissive
    peaks = frames if sphere else frames[:1]
    comp = rng.integers(0, 2 * len(peaks), m)  # even: uniform; odd: peak (comp // 2)
    d = uniform_sphere(rng, m)
    if not sphere:
        d[:, 2] = np.abs(d[:, 2])
    ring = rng.integers(0, nring, m)
    cz = np.cos(PSI_EDGES[ring + 1]) + (np.cos(PSI_EDGES[ring]) - np.cos(PSI_EDGES[ring + 1])) * rng.random(m)
    az = 2 * np.pi * rng.random(m)
    r = np.sqrt(np.maximum(0.0, 1 - cz * cz))
    loc = np.stack([r * np.cos(az), r * np.sin(az), cz], -1)
    for k, fr in enumerate(peaks):
        sel = comp == 2 * k + 1
        d[sel] = loc[sel] @ fr
    q = np.full(m, 1.0 / (4 * np.pi if sphere else 2 * np.pi)) * 0.5
    ring_area = 2 * np.pi * (np.cos(PSI_EDGES[:-1]) - np.cos(PSI_EDGES[1:]))
    for fr in peaks:
        psi = np.arccos(np.clip(d @ fr[2], -1, 1))
        i = np.clip(np.searchsorted(PSI_EDGES, psi, side="right") - 1, 0, nring - 1)
        q += 0.5 / len(peaks) / (nring * ring_area[i])
    return d, q


#: |z| bound of ``cosine_over_pdf`` checks: two-sided, 1 % family-wise (Šidák) over the 45 of
#: tests/test_coated_diffuse.py and tests/test_tabulated.py.
DENSITY_K = 3.7


def cosine_over_pdf(bsdf, wi_dir, n: int, rng, mode):
    """(mean, standard error) of cos θo / pdf over ``n`` of the sampler's own directions at
    ``wi_dir`` (0 for delta samples and failed ones): ∫ cos θo dω = π over the hemisphere where
    the pdf is that of the sampler. A pdf that is off anywhere moves the mean; cos θo keeps the
    ratio bounded where the sampler's density falls like cos θo."""
    wi = np.tile(wi_dir, (n, 1))
    s = bsdf.sample(wi, rng, mode)
    ok = (s.pdf > 0) & ~s.delta & (s.wo[:, 2] > 0)
    x = np.zeros(n)
    x[ok] = s.wo[ok, 2] / s.pdf[ok]
    return float(x.mean()), float(x.std() / np.sqrt(n))
