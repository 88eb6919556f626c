"""Common pieces of the phase functions: the base class, the sample record, lane helpers.

See the package docstring (``backend/layered/phase/__init__.py``) for the conventions.
"""
from __future__ import annotations

from typing import ClassVar, NamedTuple

import numpy as np

from ...mathutil import coordinate_system, dot


class PhaseSample(NamedTuple):
    d_out: np.ndarray   # (n, 3) sampled propagation direction after scattering, unit
    weight: np.ndarray  # (n,) p/pdf: 1 for exact sampling, 0 where sampling failed
    pdf: np.ndarray     # (n,) solid-angle density of d_out (0 where sampling failed)


class SamplingStats:
    """Counts of a rejection sampler, shared by a phase and every ``take()`` of it."""

    __slots__ = ("samples", "failures", "iterations")

    def __init__(self):
        self.samples = 0      # lanes asked for a sample
        self.failures = 0     # lanes that hit the iteration cap (returned weight 0)
        self.iterations = 0   # rejection rounds run (summed over calls)

    def __repr__(self) -> str:
        return f"SamplingStats(samples={self.samples}, failures={self.failures}, iterations={self.iterations})"


def lanes(value, idx):
    """Subset a bound parameter: constants (ndim 0 or leading dimension 1) stay as they are."""
    value = np.asarray(value)
    if value.ndim == 0 or value.shape[0] == 1:
        return value
    return value[idx]


def lane_count(*values) -> int | None:
    """The number of lanes of per-lane parameters (None if all are constants)."""
    for v in values:
        v = np.asarray(v)
        if v.ndim > 0 and v.shape[0] != 1:
            return v.shape[0]
    return None


def scalar_lanes(value) -> np.ndarray:
    """A scalar parameter as () (constant) or (n,) (per lane); (1,) and (1, 1) become ()."""
    v = np.asarray(value, dtype=np.float64)
    if v.ndim == 0:
        return v
    v = v.reshape(v.shape[0], -1)[:, 0] if v.ndim > 1 else v
    return v.reshape(()) if v.shape[0] == 1 else v


def vector_lanes(value) -> np.ndarray:
    """A 3-vector parameter as (1, 3) (constant) or (n, 3) (per lane)."""
    v = np.asarray(value, dtype=np.float64)
    return v.reshape(1, 3) if v.size == 3 else v.reshape(-1, 3)


def unit_or(v: np.ndarray, fallback) -> np.ndarray:
    """Normalise rows of v; rows shorter than 1e-12 become ``fallback`` (never NaN)."""
    length = np.sqrt(dot(v, v))
    ok = length > 1e-12
    out = v / np.where(ok, length, 1.0)[..., None]
    return np.where(ok[..., None], out, np.asarray(fallback, dtype=np.float64))


def around(axis: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Directions at polar angle (cos_t, sin_t) and azimuth phi about the unit rows of ``axis``."""
    s, t = coordinate_system(axis)
    return (sin_t * np.cos(phi))[:, None] * s + (sin_t * np.sin(phi))[:, None] * t + cos_t[:, None] * axis


def around3(axis: np.ndarray, cos_t, sin_t, phi) -> np.ndarray:
    """``around`` for (3, m) unit axes (columns): directions at (cos_t, sin_t, phi) about them
    (the frame of Duff et al. 2017, as ``coordinate_system``)."""
    x, y, z = axis
    sign = np.where(z >= 0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    sc, ss = sin_t * np.cos(phi), sin_t * np.sin(phi)
    return np.stack([sc * (1.0 + sign * x * x * a) + ss * b + cos_t * x,
                     sc * (sign * b) + ss * (sign + y * y * a) + cos_t * y,
                     -sc * (sign * x) - ss * y + cos_t * z])


class Phase:
    """A phase function bound to lanes (or constant). Subclasses implement the five methods.

    ``directional`` is True when ``sigma_scale`` is not identically 1 (microflake media): the
    walk must then evaluate σt per direction.
    """

    directional: ClassVar[bool] = False
    #: True if ``sample`` is exact (weight 1 except on failure) and pdf == eval.
    exact: ClassVar[bool] = True
    type_name: ClassVar[str] = ""

    def __init__(self):
        self.stats = SamplingStats()

    # Lanes: None for a phase whose parameters are all constants (any n works).
    @property
    def n(self) -> int | None:
        return None

    def eval(self, d_in: np.ndarray, d_out: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def pdf(self, d_in: np.ndarray, d_out: np.ndarray) -> np.ndarray:
        return self.eval(d_in, d_out)

    def sample(self, d_in: np.ndarray, rng: np.random.Generator) -> PhaseSample:
        raise NotImplementedError

    def sigma_scale(self, d: np.ndarray) -> np.ndarray:
        return np.ones(d.shape[0])

    def sample3(self, d_in: np.ndarray, rng: np.random.Generator, s_in=None):
        """The layered walk's form of ``sample``: ``d_in`` (3, m). Returns (d_out (3, m),
        weight (m,), pdf (m,), reverse pdf p(−d_out → −d_in) (m,), sigma_scale(d_out) (m,) or
        None for a non-directional phase). ``s_in``: sigma_scale(d_in) if the caller has it."""
        ps = self.sample(np.ascontiguousarray(d_in.T), rng)
        rev = self.pdf(-ps.d_out, np.ascontiguousarray(-d_in.T))
        s_out = self.sigma_scale(ps.d_out) if self.directional else None
        return np.ascontiguousarray(ps.d_out.T), ps.weight, ps.pdf, rev, s_out

    def sigma3(self, d: np.ndarray) -> np.ndarray:
        """``sigma_scale`` for (3, m) directions."""
        return self.sigma_scale(np.ascontiguousarray(d.T))

    def connect(self, a: np.ndarray, b: np.ndarray, s_a=None, s_b=None):
        """For the layered connections: ``a``, ``b`` (3, m) unit directions both pointing *away*
        from the scattering point (a = towards the previous vertex, b = towards the next one).
        Returns (p(−a → b), p(−b → a)): the value (= the sampling density) of scattering light
        arriving along −a into b, and the density of the reverse choice. ``s_a``, ``s_b``: the
        callers' ``sigma_scale`` of a and b when the phase is directional (saves recomputing
        them), else ignored. This generic version goes through ``eval``/``pdf``."""
        at, bt = np.ascontiguousarray(a.T), np.ascontiguousarray(b.T)
        return self.eval(-at, bt), self.pdf(-bt, at)

    def take(self, idx) -> "Phase":
        raise NotImplementedError

    def _child(self, other: "Phase") -> "Phase":
        other.stats = self.stats
        return other
