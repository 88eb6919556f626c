"""Common pieces of the phase functions: the base class, the sample record, lane helpers.

See the package docstring (``backend/layered/phase/__init__.py``) for the conventions.
"""
from __future__ import annotations

from typing import ClassVar, NamedTuple

import numpy as np

_NO_TABLE = np.zeros((1, 1))      # the fiber-table argument of phases that do not read it

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
    """A phase function bound to lanes (or constant): a thin wrapper over the compiled per-lane
    code (backend/kernels/layered/phase.py, the same code the layered walk runs). Subclasses give
    their parameter rows (``_bind_rows``: (1 | n, phase.SIZE) float64) and ``take``.

    ``directional`` is True when ``sigma_scale`` is not identically 1 (microflake media): the
    walk must then evaluate σt per direction.
    """

    directional: ClassVar[bool] = False
    #: True if ``sample`` is exact (weight 1 except on failure) and pdf == eval.
    exact: ClassVar[bool] = True
    type_name: ClassVar[str] = ""

    def __init__(self):
        self.stats = SamplingStats()
        self._P = None

    # Lanes: None for a phase whose parameters are all constants (any n works).
    @property
    def n(self) -> int | None:
        return None

    def _bind_rows(self) -> np.ndarray:
        raise NotImplementedError

    def table(self) -> np.ndarray:
        """The table the compiled code reads beside the rows: the fiber σ table for the microflake
        fiber phase (fiber.py overrides this), a placeholder for the others, which never read it."""
        return _NO_TABLE

    def rows(self) -> np.ndarray:
        """The parameter rows the compiled code reads (bound once, shared by calls)."""
        if getattr(self, "_P", None) is None:
            self._P = self._bind_rows()
        return self._P

    def eval(self, d_in: np.ndarray, d_out: np.ndarray) -> np.ndarray:
        from ...kernels.layered import phase_batch
        a, b = _pair_rows(d_in, d_out)
        out = np.empty(a.shape[0])
        phase_batch.eval_batch(self.rows(), self.table(), a, b, out)
        return out

    def pdf(self, d_in: np.ndarray, d_out: np.ndarray) -> np.ndarray:
        return self.eval(d_in, d_out)

    def sample(self, d_in: np.ndarray, rng: np.random.Generator) -> PhaseSample:
        from ...kernels.layered import phase_batch
        a = np.ascontiguousarray(np.asarray(d_in, dtype=np.float64).reshape(-1, 3))
        n = a.shape[0]
        d_out, weight, pdf = np.empty((n, 3)), np.empty(n), np.empty(n)
        counts = np.zeros(2, np.int64)
        phase_batch.sample_batch(self.rows(), self.table(), a, draw_seed(rng), self._max_candidates(),
                                 np.zeros(2, np.uint64), d_out, weight, pdf, counts)
        self.stats.samples += n
        self.stats.failures += int(counts[0])
        self.stats.iterations += int(counts[1])
        return PhaseSample(d_out, weight, pdf)

    def _max_candidates(self) -> int:
        return 1

    def sigma_scale(self, d: np.ndarray) -> np.ndarray:
        d = np.ascontiguousarray(np.asarray(d, dtype=np.float64).reshape(-1, 3))
        if not self.directional:
            return np.ones(d.shape[0])
        from ...kernels.layered import phase_batch
        out = np.empty(d.shape[0])
        phase_batch.scale_batch(self.rows(), self.table(), d, out)
        return out

    @classmethod
    def from_params(cls, settings: dict, **params) -> "Phase":
        """The phase from its bound parameters (keyed as in backend/layered/phase_schema.py) and its
        untexturable choices (``settings``)."""
        return cls(**params)

    def take(self, idx) -> "Phase":
        raise NotImplementedError

    def _child(self, other: "Phase") -> "Phase":
        other.stats = self.stats
        other._P = None
        return other


def _pair_rows(a, b):
    a = np.asarray(a, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 3)
    n = max(a.shape[0], b.shape[0])
    return (np.ascontiguousarray(np.broadcast_to(a, (n, 3))), np.ascontiguousarray(np.broadcast_to(b, (n, 3))))


def slot_rows(type_name: str, a=0.0, v=(0.0, 0.0, 1.0), FT=_NO_TABLE) -> np.ndarray:
    """Parameter rows of a kind bound from the medium row's slots (backend/layered/phase_schema.py:
    the scalar ``a``, () or (n,), and the vector ``v``, (1 | n, 3)) by the same per-lane ``bind``
    as the walk's stacks."""
    from ...kernels.layered import phase_layout as kp
    from ...kernels.layered.phase_batch import bind_rows
    a = np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape(-1))
    v = np.ascontiguousarray(vector_lanes(v))
    P = np.zeros((max(a.size, v.shape[0]), kp.SIZE))
    bind_rows(kp.KINDS[type_name], a, v, 0, FT, P)
    return P


def draw_seed(rng: np.random.Generator) -> np.uint64:
    """A 63-bit seed for the counter-based streams of a batch call, drawn from a NumPy generator."""
    return np.uint64(rng.integers(0, 1 << 63))
