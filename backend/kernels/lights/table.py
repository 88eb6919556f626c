"""The light table: every light of a scene as typed arrays the per-lane kernels dispatch on.

``LightTable`` (a namedtuple of NumPy arrays and two scalars; n lights):

* ``kind``            (n,) int64     kind code (dispatch.KINDS: point.POINT, area.AREA, …,
                                     ENVIRONMENT, MESH)
* ``is_delta``        (n,) bool      no BSDF ray can find it (point/spot/IES, collimated, sun
                                     without angle): ``sample`` returns pdf 0, is_delta True
* ``is_infinite``     (n,) bool      seen by rays that escape the scene (sun, constant, map)
* ``is_hittable``     (n,) bool      found by ``intersect`` at a finite distance (area, sphere
                                     and soft-falloff point lights)
* ``visible_camera``  (n,) bool      a camera ray (path segment 0) may see it directly
* ``params``          (n, NP) float64  per-light numbers; columns: common.py (shared) and the kind
                                     modules (point.py, area.py, sun.py, environment.py)
* ``iparams``         (n, NI) int64    per-light integers: offsets into aux/iaux, counts, options
* ``aux``             (m,) float64   auxiliary data: IES tables, cone tables, environment texels
                                     and distributions, mesh triangles (kind modules say how)
* ``iaux``            (k,) int64     auxiliary integers (mesh emission slots, texture ids)
* ``sel_pmf``         (n,) float64   global selection probability (0: never picked)
* ``sel_active``      (a,) int64     the lights with positive power, in table order
* ``sel_dist``        (2a + 1,) float64  1-D distribution over ``sel_active`` (discrete.py)
* ``hittable``        (h,) int64     indices of the hittable lights
* ``infinite``        (i,) int64     indices of the infinite lights
* ``prim_light``      (P,) int64     per scene primitive: the mesh light that holds it, or −1
* ``prim_local``      (P,) int64     its index among that light's triangles, or −1
                                     (P = 1 + the largest emitter primitive id; 1 if none)
* ``local_selection`` int            1: select ∝ received power per point; 0: the global table
* ``sel_radius``      float          scene radius R [m] for the infinite lights' received power

Building: ``build_light_table(lights, packer, scene_radius, selection_mode)`` calls each light's
``pack(builder)``; a light asks the builder for a row (``builder.light(kind, ...)``), writes its
columns with the kind module's layout constants and appends its auxiliary arrays. The builder
knows no light maths. Textures (mesh emission) go through the shared ``ParamPacker``, so the
integrator's one ``TextureTable`` serves materials and lights alike.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from ..discrete import layout_1d
from .common import (C_POWER, C_SEL_AREA, C_SEL_INTENSITY, C_SEL_NORMAL, C_SEL_PEAK, C_SEL_POS, C_SEL_SIZE2,
                     I_SEL, NI, NP, SEL_ONE_SIDED, SEL_ONE_SIDED_PROFILE, SEL_POINT, SEL_PROFILE, SEL_UNIFORM)

LightTable = namedtuple("LightTable", [
    "kind", "is_delta", "is_infinite", "is_hittable", "visible_camera",
    "params", "iparams", "aux", "iaux",
    "sel_pmf", "sel_active", "sel_dist",
    "hittable", "infinite", "prim_light", "prim_local",
    "local_selection", "sel_radius",
])

MODES = ("local", "power")


class LightRow:
    """One light's row while the table is built: ``f`` (NP floats) and ``i`` (NI ints)."""

    def __init__(self, kind: int, delta: bool, infinite: bool, hittable: bool, visible_camera: bool):
        self.kind = int(kind)
        self.flags = (bool(delta), bool(infinite), bool(hittable), bool(visible_camera))
        self.f = np.zeros(NP)
        self.i = np.zeros(NI, np.int64)
        self.triangle_ids = None
        self.select_uniform()

    def put(self, column: int, values) -> None:
        v = np.asarray(values, dtype=np.float64).ravel()
        self.f[column:column + v.size] = v

    # how light selection weighs this light at a point (kernels/lights/selection.py)
    def select_uniform(self):
        self.i[I_SEL] = SEL_UNIFORM

    def select_point(self, position, size: float):
        self.i[I_SEL] = SEL_POINT
        self.put(C_SEL_POS, position)
        self.f[C_SEL_SIZE2] = max(float(size) ** 2, 1e-8)

    def select_profile(self, position, size: float, intensity: float):
        """A point light whose emission has a directional factor (spot cone, IES): weighed by its
        intensity towards the point; ``intensity`` = luminance × P/(4π) at factor 1."""
        self.select_point(position, size)
        self.i[I_SEL] = SEL_PROFILE
        self.f[C_SEL_INTENSITY] = float(intensity)

    def select_one_sided(self, center, normal, area: float, peak: float = 0.0):
        """``peak`` > 0: an area light with an angular profile (spread, cutoff), weighed by it
        (its columns in the row, kernels/lights/area.py); ``peak`` = 1/K (profiles.py)."""
        self.i[I_SEL] = SEL_ONE_SIDED_PROFILE if peak > 0.0 else SEL_ONE_SIDED
        self.put(C_SEL_POS, center)
        self.put(C_SEL_NORMAL, normal)
        self.f[C_SEL_AREA] = float(area)
        self.f[C_SEL_PEAK] = float(peak)


class TableBuilder:
    def __init__(self, packer, scene_radius: float = 1.0):
        self.packer = packer
        self.scene_radius = float(scene_radius)
        self.rows: list[LightRow] = []
        self._aux: list[np.ndarray] = []
        self._aux_len = 0
        self._iaux: list[np.ndarray] = []
        self._iaux_len = 0

    def light(self, kind: int, *, delta=False, infinite=False, hittable=False,
              visible_camera=False) -> LightRow:
        row = LightRow(kind, delta, infinite, hittable, visible_camera)
        self.rows.append(row)
        return row

    def aux(self, values) -> int:
        """Append float64 data; returns its offset in ``aux``."""
        v = np.ascontiguousarray(values, dtype=np.float64).ravel()
        off = self._aux_len
        self._aux.append(v)
        self._aux_len += v.size
        return off

    def iaux(self, values) -> int:
        v = np.ascontiguousarray(values, dtype=np.int64).ravel()
        off = self._iaux_len
        self._iaux.append(v)
        self._iaux_len += v.size
        return off

    def _concat(self, parts, dtype):
        return np.ascontiguousarray(np.concatenate(parts), dtype) if parts else np.zeros(1, dtype)


def build_light_table(lights, packer, scene_radius: float = 1.0, selection_mode: str = "local",
                      powers=None) -> LightTable:
    """The table of ``lights`` (in order: light i is row i). ``powers`` overrides
    ``light.power()`` (selection weights; non-finite or ≤ 0 → never picked)."""
    if selection_mode not in MODES:
        raise ValueError(f"unknown light selection mode {selection_mode!r} (known: {', '.join(MODES)})")
    b = TableBuilder(packer, scene_radius)
    for light in lights:
        before = len(b.rows)
        light.pack(b)
        if len(b.rows) != before + 1:
            raise RuntimeError(f"{type(light).__name__}.pack must add exactly one light row")
    n = len(b.rows)
    if powers is None:
        powers = [float(light.power()) for light in lights]
    p = np.asarray(powers, dtype=np.float64).reshape(n) if n else np.zeros(0)
    p = np.where(np.isfinite(p) & (p > 0), p, 0.0)
    params = np.zeros((max(n, 1), NP))
    iparams = np.zeros((max(n, 1), NI), np.int64)
    flags = np.zeros((4, max(n, 1)), bool)
    kind = np.full(max(n, 1), -1, np.int64)
    for k, row in enumerate(b.rows):
        params[k] = row.f
        iparams[k] = row.i
        flags[:, k] = row.flags
        kind[k] = row.kind
    params[:n, C_POWER] = p
    active = np.nonzero(p > 0)[0].astype(np.int64)
    sel_pmf = np.zeros(max(n, 1))
    if active.size:
        _, pmf, _, sel_dist = layout_1d(p[active])
        sel_pmf[active] = pmf
    else:
        sel_dist = np.zeros(1)
    # scene primitives → (mesh light, local triangle)
    ids = [(k, np.asarray(getattr(light, "triangle_ids"), np.int64)) for k, light in enumerate(lights)
           if getattr(light, "triangle_ids", None) is not None]
    size = 1 + max((int(t.max()) for _, t in ids if t.size), default=0)
    prim_light = np.full(size, -1, np.int64)
    prim_local = np.full(size, -1, np.int64)
    for k, t in ids:
        prim_light[t] = k
        prim_local[t] = np.arange(t.size)
    if n == 0:
        flags[:] = False
    return LightTable(
        kind=kind, is_delta=flags[0].copy(), is_infinite=flags[1].copy(), is_hittable=flags[2].copy(),
        visible_camera=flags[3].copy(), params=params, iparams=iparams,
        aux=b._concat(b._aux, np.float64), iaux=b._concat(b._iaux, np.int64),
        sel_pmf=sel_pmf, sel_active=active, sel_dist=np.ascontiguousarray(sel_dist, np.float64),
        hittable=np.nonzero(flags[2][:n])[0].astype(np.int64),
        infinite=np.nonzero(flags[1][:n])[0].astype(np.int64),
        prim_light=prim_light, prim_local=prim_local,
        local_selection=int(selection_mode == "local" and active.size > 1),
        sel_radius=max(float(scene_radius), 1e-6))


def light_count(table: LightTable) -> int:
    """Number of lights (the arrays keep one dummy row when there are none)."""
    return int(np.count_nonzero(table.kind >= 0))
