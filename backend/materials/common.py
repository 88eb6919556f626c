"""Small helpers shared by the standard materials (parameters, lanes, hemisphere handling)."""
from __future__ import annotations

import numpy as np

from ..mathutil import outer3, scale_rows
from ..textures import ConstantParam, Param
from .microfacet import DISTRIBUTIONS, MASKINGS


def as_param(value, channels: int) -> Param:
    """A Param as is; a number / RGB triple becomes a constant (for building materials in code)."""
    if isinstance(value, Param):
        return value
    v = np.asarray(value, dtype=np.float64)
    if channels == 3 and v.size == 1:
        v = np.full(3, float(v))
    return ConstantParam(v, channels)


def times_color(s: np.ndarray, color: np.ndarray) -> np.ndarray:
    """(n, 3) rows s·colour for a per-lane scalar s and a constant (1, 3) or per-lane (n, 3) colour,
    without numpy's slow (n, 1) broadcasting (mathutil.outer3 / scale_rows)."""
    s = np.asarray(s, dtype=np.float64)
    color = np.asarray(color, dtype=np.float64)
    if color.ndim == 1 or color.shape[0] == 1:
        return outer3(s, color.reshape(3))
    return scale_rows(s, color)


def col(x) -> np.ndarray:
    """A per-lane scalar as a column that broadcasts against (n, 3): () → (1,), (n,) → (n, 1)."""
    return np.asarray(x)[..., None]


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def normalize(v: np.ndarray) -> np.ndarray:
    n = np.sqrt(dot(v, v))
    return v / np.where(n > 0, n, 1.0)[:, None]


def mirror_z(w: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """w with its z component multiplied by ``sign`` (±1 per lane)."""
    out = w.copy()
    out[:, 2] *= sign
    return out


def upper_side(wi: np.ndarray):
    """For reflection-only BSDFs (two-sided): the sign that mirrors wi into the upper hemisphere.

    The integrator already turns the frame towards the viewer; handling wi.z < 0 here as well
    (by mirroring both directions through the surface plane) keeps these BSDFs usable from
    either side inside layered stacks.
    """
    return np.where(wi[:, 2] < 0, -1.0, 1.0)


def parse_roughness(node, default: float):
    """``roughness`` (α along the UV tangent, local x) and optional ``roughness_v`` (α along y)."""
    ru = node.param("roughness", default, lo=0.0, hi=1.0, color=False)
    rv = node.param("roughness_v", lo=0.0, hi=1.0, color=False) if node.has("roughness_v") else ru
    node.ignore("roughness_v")
    return ru, rv


def parse_microfacet_kind(node):
    dist = node.string("distribution", "ggx", choices=DISTRIBUTIONS)
    masking = node.string("masking", "height-correlated", choices=MASKINGS)
    return dist, masking


def delta_lanes(alpha_u: np.ndarray, alpha_v: np.ndarray) -> np.ndarray:
    """Lanes whose roughness is exactly 0 in both directions are smooth (delta lobes)."""
    return (np.asarray(alpha_u) <= 0.0) & (np.asarray(alpha_v) <= 0.0)
