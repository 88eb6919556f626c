"""The light interface. All queries are vectorised over n shading points, world space, float64.

Units follow Cycles ≥ 4.0 (DESIGN.md §3): the scene file stores Blender's own fields (power in W,
colour, strength, angles in degrees) and each light converts them to radiance/intensity here, in
one place.

* ``sample(p, u)`` picks a point/direction on the light for next-event estimation from points p
  (n, 3) with uniform numbers u (n, 2). It returns a :class:`LightSample` whose ``value`` is the
  incident radiance divided by the solid-angle pdf (for delta lights: the irradiance-like weight
  I/r² etc.), so the contribution is ``f·|cos| × value``. ``pdf`` is the solid-angle density (0 for
  delta lights); it excludes the light-selection probability, which the integrator applies.
* Lights that a BSDF-sampled ray can hit (area, sphere, environment, sun with an angle) implement
  ``intersect`` / ``eval_hit`` (finite) or ``eval_escaped`` (infinite) plus ``pdf_hit`` for MIS.
* ``power()`` is an estimate of emitted power in W (luminance of RGB) used only for light
  selection; it must be > 0 for a light that emits anything.
"""
from __future__ import annotations

from typing import ClassVar, NamedTuple

import numpy as np


class LightSample(NamedTuple):
    wi: np.ndarray      # (n, 3) unit direction from the shading point towards the light
    dist: np.ndarray    # (n,) distance to the sampled point (np.inf for infinitely far lights)
    value: np.ndarray   # (n, 3) radiance / pdf (or delta-light equivalent); 0 where invalid
    pdf: np.ndarray     # (n,) solid-angle pdf of this direction (0 for delta lights)


class Light:
    #: A delta light (point, spot, IES, sun without angle) cannot be hit by BSDF rays.
    is_delta: ClassVar[bool] = False
    #: An infinitely distant light (environment, sun): seen by rays that escape the scene.
    is_infinite: ClassVar[bool] = False
    #: Can rays hit it at a finite distance (analytic area/sphere lights)?
    is_hittable: ClassVar[bool] = False

    def prepare(self, scene_center: np.ndarray, scene_radius: float) -> None:
        """Called once the scene bounds are known (infinite lights need them for power)."""

    def power(self) -> float:
        raise NotImplementedError

    def sample(self, p: np.ndarray, u: np.ndarray) -> LightSample:
        raise NotImplementedError

    # finite hittable lights (area rectangle/disk/ellipse, sphere point/spot lights)
    def intersect(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray) -> np.ndarray:
        """Ray parameter t of the first hit in (0, tmax), np.inf where none. d is unit."""
        raise NotImplementedError

    def eval_hit(self, o: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Radiance (n, 3) arriving at o from direction d, emitted at o + t d."""
        raise NotImplementedError

    def pdf_hit(self, o: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Solid-angle pdf with which ``sample(o, .)`` would have produced direction d."""
        raise NotImplementedError

    # infinite lights
    def eval_escaped(self, d: np.ndarray) -> np.ndarray:
        """Radiance (n, 3) arriving along -d for rays escaping in direction d."""
        raise NotImplementedError

    def pdf_escaped(self, d: np.ndarray) -> np.ndarray:
        raise NotImplementedError
