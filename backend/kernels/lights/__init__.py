"""Lights as per-lane compiled code: one module per light kind, a typed light table, dispatch.

* ``table.py``     — ``LightTable`` (typed arrays) and ``build_light_table``; each Light class
  (backend/lights/*.py) writes its own row with ``pack(builder)``.
* ``dispatch.py``  — the per-lane interface the integrator kernels call (sample, intersect,
  eval/pdf of hits and escaped rays, mesh-triangle pdf, selection).
* ``point.py`` (point/sphere/soft-falloff disk), ``spot.py`` (cone falloff), ``ies.py`` (IES
  profiles), ``area.py`` + ``profiles.py`` (area, directional and collimated area lights),
  ``sun.py``, ``environment.py`` (constant world, environment map), ``mesh.py`` (emissive
  triangles), ``selection.py`` (light selection), ``common.py`` (kinds, shared columns).
* ``batch.py``     — array loops over the per-lane functions for NumPy callers.

Import through the ``backend.kernels`` package (kernels/__init__.py fixes the cache folder).
"""
