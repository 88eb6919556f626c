"""Light selection for next-event estimation: probability ∝ ``Light.power()``.

Lights whose power is zero (or not finite) are never picked — not even at the ties of the
cumulative distribution — and have selection probability 0 for MIS. ``build_selector`` returns
None when nothing in the scene emits.
"""
from __future__ import annotations

import numpy as np

from ..sampling.discrete import Discrete1D


class LightSelector:
    def __init__(self, powers):
        p = np.asarray(powers, dtype=np.float64).ravel()
        p = np.where(np.isfinite(p) & (p > 0), p, 0.0)
        self.active = np.nonzero(p > 0)[0]
        if self.active.size == 0:
            raise ValueError("LightSelector needs at least one light with positive power")
        self._dist = Discrete1D(p[self.active])
        #: selection probability of every light (0 for lights that are never picked)
        self.pmf = np.zeros(p.size)
        self.pmf[self.active] = self._dist.pmf

    def __len__(self) -> int:
        return self.pmf.size

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """u (n,) in [0, 1) → (light index, its probability, u remapped to [0, 1) in its bin)."""
        k, prob, u_rem = self._dist.sample(np.asarray(u, dtype=np.float64))
        return self.active[k], prob, u_rem

    def prob(self, light_index) -> np.ndarray | float:
        """Selection probability of the given light(s), for MIS weights."""
        return self.pmf[light_index]


def build_selector(lights) -> LightSelector | None:
    powers = np.array([max(float(light.power()), 0.0) for light in lights]) if lights else np.zeros(0)
    if powers.size == 0 or not np.any(np.isfinite(powers) & (powers > 0)):
        return None
    return LightSelector(powers)
