"""The closed form of a dielectric over a Lambertian body (backend/kernels/bsdf/coated_diffuse.py
has the maths): which stacks qualify, and their tables.

A stack qualifies when, after flattening, it is exactly [dielectric, diffuse] with one slab
between them that is empty or purely absorbing (albedo 0), with
* the dielectric isotropic (``roughness_v`` absent or equal), its tint constant, no normal or
  bump map on either interface (a whole-material map is fine: the integrator applies it);
* the slab's thickness and σt constant.
The body's colour and the dielectric's roughness may be textures (a roughness texture makes the
tables span α on a grid of ``ALPHA_NODES`` nodes). Everything else keeps the walk.

Tables: one block per distinct (η, tint, α or the α grid, distribution, masking, τ), computed
once per process (``table``). Cost measured on the development machine: one roughness node
≈ 0.05 s, the α grid ≈ 1 s (docs/materials.md).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..kernels.microfacet_codes import DISTRIBUTION_CODES, MASKING_CODES

ALPHA_NODES = 17            # a roughness texture: nodes uniform in √α on [0, 1]
STRATA = 64                 # visible normals per table integral: STRATA² (a Fibonacci lattice)
GAUSS_NODES = 48            # Gauss–Legendre nodes of r and Ē


def _exit_distribution(node: np.ndarray, kc) -> None:
    """The body's exit distribution over μ² (kernels/bsdf/coated_diffuse.py): the channel mean of
    E at each interval's middle, normalised to mean 1 (a floor keeps every direction possible),
    and its running sum / NU."""
    mu_nodes = np.linspace(0.0, 1.0, kc.NMU)
    e = node[kc.E_AT:kc.E_AT + 3 * kc.NMU].reshape(3, kc.NMU).mean(axis=0)
    mid = np.sqrt((np.arange(kc.NU) + 0.5) / kc.NU)
    h = np.maximum(np.interp(mid, mu_nodes, e), 1e-6)
    h = np.maximum(h / h.mean(), 1e-3)
    h /= h.mean()
    node[kc.ES_AT:kc.ES_AT + kc.NU] = h
    cdf = np.concatenate([[0.0], np.cumsum(h) / kc.NU])
    cdf[-1] = 1.0
    node[kc.CDF_AT:kc.CDF_AT + kc.NU + 1] = cdf


def qualifies(flat) -> dict | None:
    """The closed form's parameters of a flattened stack (layered/flat.Flat), or None."""
    if len(flat.interfaces) != 2 or any(n is not None for n in flat.normals):
        return None
    top, body = flat.interfaces
    if getattr(top, "type_name", "") != "dielectric" or getattr(body, "type_name", "") != "diffuse":
        return None
    if not (top.roughness_v is top.roughness or (top.roughness.is_constant and top.roughness_v.is_constant
                                                 and float(top.roughness.mean()) == float(top.roughness_v.mean()))):
        return None
    if not (top.transmission_color.is_constant and top.ior.is_constant):
        return None
    medium = flat.media[0]
    if not (medium.thickness.is_constant and medium.sigma_t.is_constant):
        return None
    tau = np.broadcast_to(np.asarray(medium.sigma_t.mean(), dtype=np.float64).reshape(-1), (3,)) * \
        float(np.asarray(medium.thickness.mean()).reshape(-1)[0])
    if np.any(tau > 0.0) and not (medium.albedo.is_constant and not np.any(medium.albedo.mean())):
        return None                                  # a scattering medium
    eta = float(np.asarray(top.ior.mean()).reshape(-1)[0]) / float(top.ior_above)
    if eta == 1.0:
        return None                                  # an index-matched interface is a null one
    return {"eta": eta, "tint": tuple(float(x) for x in np.asarray(top.transmission_color.mean()).reshape(3)),
            "tau": tuple(float(x) for x in tau), "dist": top.distribution, "masking": top.masking,
            "roughness": top.roughness, "color": body.color}


def table(eta: float, tint: tuple, alpha: float | None, dist: str, masking: str, tau: tuple) -> np.ndarray:
    """The table block (kernels/bsdf/coated_diffuse.py layout) for a constant roughness α, or
    for the α grid (``alpha`` None)."""
    return _table(float(eta), tuple(map(float, tint)), None if alpha is None else float(alpha),
                  DISTRIBUTION_CODES[dist], MASKING_CODES[masking], tuple(map(float, tau)))


@lru_cache(maxsize=256)
def _table(eta, tint, alpha, dist, masking, tau) -> np.ndarray:
    from ..kernels.bsdf import coated_diffuse as kc
    alphas = [alpha] if alpha is not None else list(np.linspace(0.0, 1.0, ALPHA_NODES) ** 2)
    out = np.zeros(kc.HEAD + len(alphas) * kc.NODE)
    out[0] = len(alphas)
    out[1] = 1.0 / (eta * eta)
    x, w = np.polynomial.legendre.leggauss(GAUSS_NODES)
    gl_x = np.ascontiguousarray(0.5 * (x + 1.0))
    gl_w = np.ascontiguousarray(0.5 * w)
    for k, a in enumerate(alphas):
        smooth = a <= 0.0
        node = np.zeros(kc.NODE)
        kc.integrate_node(eta, tint, max(a, 1e-4), smooth, dist, masking, tau, STRATA, gl_x, gl_w, node)
        _exit_distribution(node, kc)
        out[kc.HEAD + k * kc.NODE: kc.HEAD + (k + 1) * kc.NODE] = node
    out.setflags(write=False)
    return out
