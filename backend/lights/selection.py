"""Light selection for next-event estimation: probability ∝ each light's power.

Two modes (scene ``render.light_selection``):

* ``"power"`` — probability ∝ ``Light.power()`` everywhere (one global table).
* ``"local"`` (default) — probability ∝ the light's power *as received at the shading point*
  (an unoccluded irradiance scale in W/m², per lane; distant lights: P/(πR²) = E; capped at the
  light's size nearby; one-sided area lights give 0 behind themselves).

The per-lane choice and its probability are compiled code (``backend/kernels/lights/
selection.py``, whose docstring has the details and the measurement that motivates local
selection); ``LightSelector`` builds the light table for them and loops them over arrays.
Lights whose power is zero (or not finite) are never picked and have selection probability 0 for
MIS. ``build_selector`` returns None when nothing in the scene emits. Per-lane probabilities are
exact (they are what MIS uses), whatever the mode.
"""
from __future__ import annotations

import numpy as np

from ..kernels.lights import batch as _batch
from ..sampling.discrete import Discrete1D

MODES = ("local", "power")


class LightSelector:
    def __init__(self, powers, lights=None, mode: str = "power", radius: float = 1.0):
        p = np.asarray(powers, dtype=np.float64).ravel()
        p = np.where(np.isfinite(p) & (p > 0), p, 0.0)
        self.powers = p
        self.active = np.nonzero(p > 0)[0]
        if self.active.size == 0:
            raise ValueError("LightSelector needs at least one light with positive power")
        self._dist = Discrete1D(p[self.active])
        #: global selection probability of every light (0 for lights that are never picked)
        self.pmf = np.zeros(p.size)
        self.pmf[self.active] = self._dist.pmf
        self.lights = list(lights) if lights is not None else None
        self.local = mode == "local" and self.lights is not None and self.active.size > 1
        self.radius = max(float(radius), 1e-6)
        self._table = None

    def __len__(self) -> int:
        return self.pmf.size

    def table(self):
        """The light table of the lights with these powers and this mode (built once)."""
        if self._table is None:
            from ..kernels.lights.table import build_light_table
            from ..kernels.params import ParamPacker
            self._table = build_light_table(self.lights, ParamPacker(), self.radius,
                                            "local" if self.local else "power", powers=self.powers)
        return self._table

    # ------------------------------------------------------------------ global table
    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """u (n,) in [0, 1) → (light index, its probability, u remapped to [0, 1) in its bin)."""
        k, prob, u_rem = self._dist.sample(np.asarray(u, dtype=np.float64))
        return self.active[k], prob, u_rem

    def prob(self, light_index) -> np.ndarray | float:
        """Global selection probability of the given light(s)."""
        return self.pmf[light_index]

    # ------------------------------------------------------------------ per shading point
    def weights_at(self, p: np.ndarray) -> np.ndarray:
        """(n, len(active)) received-power weights of the active lights at points p."""
        p = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 3)
        out = np.empty((p.shape[0], self.active.size))
        col = np.empty(p.shape[0])
        for k, i in enumerate(self.active):
            _batch.received_power(self.table(), int(i), p, col)
            out[:, k] = col
        return out

    def sample_at(self, p: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-lane choice at points p: (light index, its probability)."""
        if self.lights is None:
            idx, prob, _ = self.sample(u)
            return idx, prob
        p = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 3)
        u = np.ascontiguousarray(np.broadcast_to(np.asarray(u, dtype=np.float64).reshape(-1), (p.shape[0],)))
        idx = np.empty(p.shape[0], np.int64)
        prob = np.empty(p.shape[0])
        _batch.select(self.table(), p, u, idx, prob)
        return idx, prob

    def prob_at(self, p: np.ndarray, light_index: int) -> np.ndarray:
        """Selection probability of one light at points p (for MIS of light hits)."""
        if self.lights is None:
            return np.full(np.asarray(p).shape[0], self.pmf[light_index])
        p = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 3)
        out = np.empty(p.shape[0])
        _batch.select_prob(self.table(), p, np.array([light_index], np.int64), out)
        return out


def received_power(light, power: float, p: np.ndarray, radius: float) -> np.ndarray:
    """Power of ``light`` as received at points p (W/m² scale; kernels/lights/selection.py)."""
    from ..kernels.lights.table import build_light_table
    from ..kernels.params import ParamPacker
    table = build_light_table([light], ParamPacker(), max(float(radius), 1e-6), "power", powers=[power])
    p = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 3)
    out = np.empty(p.shape[0])
    _batch.received_power(table, 0, p, out)
    return out


def build_selector(lights, mode: str = "local", radius: float = 1.0) -> LightSelector | None:
    powers = np.array([max(float(light.power()), 0.0) for light in lights]) if lights else np.zeros(0)
    if powers.size == 0 or not np.any(np.isfinite(powers) & (powers > 0)):
        return None
    return LightSelector(powers, lights, mode, radius)
