"""The light interface. All queries are vectorised over n shading points, world space, float64.

Units follow Cycles ≥ 4.0 (docs/lights.md): the scene file stores Blender's own fields (power in W,
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

The per-lane maths of every query is compiled code (``backend/kernels/lights/``, dispatch.py has
the per-lane interface the integrator kernels call); these methods loop it over arrays.
"""
from __future__ import annotations

from typing import ClassVar, NamedTuple

import numpy as np

from ..kernels.lights import batch as _batch


class LightSample(NamedTuple):
    wi: np.ndarray      # (n, 3) unit direction from the shading point towards the light
    dist: np.ndarray    # (n,) distance to the sampled point (np.inf for infinitely far lights)
    value: np.ndarray   # (n, 3) radiance / pdf (or delta-light equivalent); 0 where invalid
    pdf: np.ndarray     # (n,) solid-angle pdf of this direction (0 for delta lights)


_LI0 = np.zeros(1, np.int64)      # light 0 of a one-light table, for every lane


def _rows(a, k: int = 3) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape(-1, k))


def _lanes(a, n: int) -> np.ndarray:
    return np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=np.float64).reshape(-1), (n,)))


class Light:
    """A light: scene-file parsing, units and power estimates here (NumPy, load time); the per-lane
    maths is compiled code in ``backend/kernels/lights/`` (one module per kind). ``pack(builder)``
    writes the light's row of the light table; the array methods below run the same per-lane code
    the integrator kernels call, through a one-light table cached on the instance."""

    #: A delta light (point, spot, IES, sun without angle) cannot be hit by BSDF rays.
    is_delta: ClassVar[bool] = False
    #: An infinitely distant light (environment, sun): seen by rays that escape the scene.
    is_infinite: ClassVar[bool] = False
    #: Can rays hit it at a finite distance (analytic area/sphere lights)?
    is_hittable: ClassVar[bool] = False
    #: Does next-event estimation sample it? (A constant world is left to BSDF sampling.)
    light_sampled: ClassVar[bool] = True
    #: Is it seen in every direction (an environment)? Then every ray that escapes needs its MIS
    #: weight, and the integrator estimates layered continuations' pdfs at once (integrator.py).
    fills_sphere: ClassVar[bool] = False

    def prepare(self, scene_center: np.ndarray, scene_radius: float) -> None:
        """Called once the scene bounds are known (infinite lights need them for power)."""

    def power(self) -> float:
        raise NotImplementedError

    def pack(self, builder) -> None:
        """Add this light's row to a light table (backend/kernels/lights/table.py)."""
        raise NotImplementedError

    def kernel_table(self):
        """(LightTable, TextureTable) holding this light alone, built once (selection off)."""
        kt = self.__dict__.get("_kernel_table")
        if kt is None:
            from ..kernels.lights.table import build_light_table
            from ..kernels.params import ParamPacker
            packer = ParamPacker()
            table = build_light_table([self], packer, 1.0, "power", powers=[0.0])
            kt = (table, packer.table())
            self._kernel_table = kt
        return kt

    def sample(self, p: np.ndarray, u: np.ndarray) -> LightSample:
        table, tex = self.kernel_table()
        p, u = _rows(p), _rows(u, 2)
        n = p.shape[0]
        wi, dist, value, pdf = np.empty((n, 3)), np.empty(n), np.empty((n, 3)), np.empty(n)
        _batch.sample(table, tex, _LI0, p, u, wi, dist, value, pdf, np.empty(n, bool))
        return LightSample(wi, dist, value, pdf)

    # finite hittable lights (area rectangle/disk/ellipse, sphere point/spot lights)
    def intersect(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray) -> np.ndarray:
        """Ray parameter t of the first hit in (0, tmax), np.inf where none. d is unit."""
        o, d = _rows(o), _rows(d)
        out = np.empty(o.shape[0])
        _batch.intersect(self.kernel_table()[0], _LI0, o, d, _lanes(tmax, o.shape[0]), out)
        return out

    def eval_hit(self, o: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Radiance (n, 3) arriving at o from direction d, emitted at o + t d."""
        o, d = _rows(o), _rows(d)
        out = np.empty((o.shape[0], 3))
        _batch.eval_hit(self.kernel_table()[0], _LI0, o, d, _lanes(t, o.shape[0]), out)
        return out

    def pdf_hit(self, o: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Solid-angle pdf with which ``sample(o, .)`` would have produced direction d."""
        o, d = _rows(o), _rows(d)
        out = np.empty(o.shape[0])
        _batch.pdf_hit(self.kernel_table()[0], _LI0, o, d, _lanes(t, o.shape[0]), out)
        return out

    # infinite lights
    def eval_escaped(self, d: np.ndarray) -> np.ndarray:
        """Radiance (n, 3) arriving along -d for rays escaping in direction d."""
        d = _rows(d)
        out = np.empty((d.shape[0], 3))
        _batch.eval_escaped(self.kernel_table()[0], _LI0, d, out)
        return out

    def pdf_escaped(self, d: np.ndarray) -> np.ndarray:
        d = _rows(d)
        out = np.empty(d.shape[0])
        _batch.pdf_escaped(self.kernel_table()[0], _LI0, d, out)
        return out
