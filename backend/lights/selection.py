"""Light selection for next-event estimation: probability ∝ each light's power.

Two modes (scene ``render.light_selection``):

* ``"power"`` — probability ∝ ``Light.power()`` everywhere (one global table).
* ``"local"`` (default) — probability ∝ the light's power *as received at the shading point*: the
  power spread over the sphere at the point's distance, i.e. an unoccluded irradiance scale in
  W/m², computed per lane. Distant lights ("infinite": sun, world) have no distance; their power is
  defined over the scene's bounding disk (P = E·πR²), so their received scale is P/(πR²) = E.
  A light very close to a point is capped at its own size (no division by ~0). One-sided area
  lights give 0 behind themselves, where they cannot contribute. This matters as soon as lights
  differ in distance: with a global table a 40 m sunlit floor made a nearby 400 W area light get
  6 % of the samples and the render noise 4× higher than with local selection (measured on the
  demo scene's floor).

Lights whose power is zero (or not finite) are never picked and have selection probability 0 for
MIS. ``build_selector`` returns None when nothing in the scene emits. Per-lane probabilities are
exact (they are what MIS uses), whatever the mode.
"""
from __future__ import annotations

import numpy as np

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

    def __len__(self) -> int:
        return self.pmf.size

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
        cols = [received_power(self.lights[i], self.powers[i], p, self.radius) for i in self.active]
        return np.stack(cols, axis=1)

    def sample_at(self, p: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-lane choice at points p: (light index, its probability)."""
        if not self.local:
            idx, prob, _ = self.sample(u)
            return idx, prob
        w = self.weights_at(p)
        total = w.sum(axis=1)
        # Where nothing can reach the point fall back to the global table (contributions are 0).
        w = np.where(total[:, None] > 0, w, self.powers[self.active][None, :])
        cdf = np.cumsum(w, axis=1)
        cdf /= cdf[:, -1:]
        k = (u[:, None] >= cdf).sum(axis=1)
        k = np.minimum(k, self.active.size - 1)
        # A bin of zero width is never chosen by the comparison above except through rounding at
        # the very top; step back to the last positive bin then.
        rows = np.arange(k.size)
        zero = w[rows, k] <= 0
        if zero.any():
            k[zero] = w.shape[1] - 1 - np.argmax(w[zero][:, ::-1] > 0, axis=1)
        prob = w[rows, k] / w.sum(axis=1)
        return self.active[k], prob

    def prob_at(self, p: np.ndarray, light_index: int) -> np.ndarray:
        """Selection probability of one light at points p (for MIS of light hits)."""
        if not self.local:
            return np.full(p.shape[0], self.pmf[light_index])
        if self.powers[light_index] <= 0:
            return np.zeros(p.shape[0])
        w = self.weights_at(p)
        total = w.sum(axis=1)
        col = int(np.searchsorted(self.active, light_index))
        fallback = self.pmf[light_index]
        return np.where(total > 0, w[:, col] / np.where(total > 0, total, 1.0), fallback)


def received_power(light, power: float, p: np.ndarray, radius: float) -> np.ndarray:
    """Power of ``light`` as received at points p (W/m² scale; see module docstring)."""
    custom = getattr(light, "received_power", None)
    if custom is not None:
        return np.asarray(custom(p, power), dtype=np.float64)
    n = p.shape[0]
    position = getattr(light, "position", None)
    if light.is_infinite or position is None:
        return np.full(n, power / (np.pi * radius * radius))
    d = p - np.asarray(position, dtype=np.float64)
    d2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
    size = float(getattr(light, "extent", 0.0) or getattr(light, "radius", 0.0) or 0.0)
    return power / (4.0 * np.pi * np.maximum(d2, max(size * size, 1e-8)))


def build_selector(lights, mode: str = "local", radius: float = 1.0) -> LightSelector | None:
    powers = np.array([max(float(light.power()), 0.0) for light in lights]) if lights else np.zeros(0)
    if powers.size == 0 or not np.any(np.isfinite(powers) & (powers > 0)):
        return None
    return LightSelector(powers, lights, mode, radius)
