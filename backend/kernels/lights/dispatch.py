"""The per-lane light interface the integrator kernels call (one light table ``lt``, table.py;
the scene's ``TextureTable`` ``tx``, kernels/textures.py). World space, float64, directions are
unit 3-tuples pointing away from the shading point.

* ``sample(lt, tx, li, p, u0, u1) -> (wi, dist, value, pdf, is_delta)``: a direction towards
  light ``li`` from point p for next-event estimation. ``value`` is the incident radiance divided
  by the solid-angle pdf (delta lights: the irradiance-like weight, e.g. I/d²), so the
  contribution is f·|cos| × value; ``pdf`` excludes the selection probability and is 0 for delta
  lights; ``dist`` is the distance to the sampled point (inf for infinitely far lights: trace the
  shadow ray to infinity); value and pdf are 0 where the light cannot reach p (no shadow ray).
* ``intersect(lt, li, o, d, tmax) -> t``: first hit in (0, tmax) of a finite hittable light
  (area, sphere, soft-falloff disk), inf otherwise and for every other kind.
* ``eval_hit(lt, li, o, d, t) -> rgb``, ``pdf_hit(lt, li, o, d, t) -> pdf``: radiance arriving
  at o along d from the hit at o + t d, and the solid-angle density ``sample(o)`` gives d.
* ``eval_escaped(lt, li, d)``, ``pdf_escaped(lt, li, d)``: the same for rays escaping the scene
  in direction d (sun with an angle, constant world, environment map; 0 for the others).
* ``mesh_pdf_hit(lt, li, o, d, t, local_tri)``: the density of a hit on emitter triangle
  ``local_tri`` of mesh light li (``emitter_of_prim`` maps a scene primitive to both).
* ``select(lt, p, u) -> (li, prob)``, ``select_prob(lt, p, li)``: light selection (selection.py).

All of these are inlined into the calling kernel (``@inlined``, kernels/jit.py) and call the kind's own
function with the table's arrays and the light's row index (common.py: no row views). Reading an
array out of the table (``lt.params``) inside a lane is a new reference for Numba: an atomic
increment and a decrement call per array, which LLVM cannot remove around calls that are not
inlined. Measured on 1M lanes (benchmarks/light_kernels.py, one point light): 145 ns per sample
with reference counting, 40 ns without. A lane loop should therefore be compiled with
``_nrt=False`` (it allocates nothing; every ``@kernel`` is), or read the table's arrays into
locals once, outside the loop, and call the kind modules directly.

Units and conventions of each kind are in its module (point.py, spot.py, ies.py, area.py,
profiles.py, sun.py, environment.py, mesh.py).
"""
from __future__ import annotations

from ..jit import inlined
from ..consts import INV_4PI
from . import area as _area
from . import environment as _env
from . import mesh as _mesh
from . import point as _point
from . import selection as _sel
from . import sun as _sun
from .area import AREA, COLLIMATED
from .common import INF, ZERO3
from .environment import CONSTANT, ENVIRONMENT
from .mesh import MESH
from .point import POINT
from .sun import SUN

#: The family's kinds: code → name. Each kind's code lives in its own kernel module; a test
#: (tests/test_kind_dispatch.py) checks that the codes are unique and that every dispatcher below
#: has a branch for exactly the kinds ANSWERS gives it.
KINDS = {POINT: "point", AREA: "area", COLLIMATED: "collimated", SUN: "sun", CONSTANT: "constant",
         ENVIRONMENT: "environment", MESH: "mesh"}
HITTABLE = (POINT, AREA)                  # lights a ray can hit (a surface in space)
ESCAPED = (SUN, CONSTANT, ENVIRONMENT)    # lights a ray that leaves the scene sees
ANSWERS = {"sample": tuple(KINDS), "intersect": HITTABLE, "eval_hit": HITTABLE, "pdf_hit": HITTABLE,
           "eval_escaped": ESCAPED, "pdf_escaped": ESCAPED, "mesh_pdf_hit": (MESH,), "mesh_eval": (MESH,)}


@inlined
def sample(lt, tx, li, p, u0, u1):
    k = lt.kind[li]
    P = lt.params
    I = lt.iparams
    if k == POINT:
        wi, dist, value, pdf = _point.sample(P, I, li, lt.aux, p, u0, u1)
    elif k == AREA:
        wi, dist, value, pdf = _area.sample(P, I, li, lt.aux, p, u0, u1)
    elif k == SUN:
        wi, dist, value, pdf = _sun.sample(P, I, li, u0, u1)
    elif k == ENVIRONMENT:
        wi, dist, value, pdf = _env.env_sample(P, I, li, lt.aux, u0, u1)
    elif k == MESH:
        wi, dist, value, pdf = _mesh.sample(I, li, lt.aux, lt.iaux, tx, p, u0, u1)
    elif k == CONSTANT:
        wi, dist, value, pdf = _env.constant_sample(P, li, u0, u1)
    elif k == COLLIMATED:
        wi, dist, value, pdf = _area.sample_collimated(P, I, li, p)
    else:
        wi, dist, value, pdf = ZERO3, 0.0, ZERO3, 0.0
    return wi, dist, value, pdf, lt.is_delta[li]


@inlined
def intersect(lt, li, o, d, tmax):
    k = lt.kind[li]
    if k == AREA:
        return _area.intersect(lt.params, lt.iparams, li, o, d, tmax)
    if k == POINT:
        return _point.intersect(lt.params, lt.iparams, li, o, d, tmax)
    return INF


@inlined
def eval_hit(lt, li, o, d, t):
    k = lt.kind[li]
    if k == AREA:
        return _area.eval_hit(lt.params, lt.iparams, li, o, d, t)
    if k == POINT:
        return _point.eval_hit(lt.params, lt.iparams, li, lt.aux, o, d, t)
    return ZERO3


@inlined
def pdf_hit(lt, li, o, d, t):
    k = lt.kind[li]
    if k == AREA:
        return _area.pdf_hit(lt.params, lt.iparams, li, lt.aux, o, d, t)
    if k == POINT:
        return _point.pdf_hit(lt.params, lt.iparams, li, o, d, t)
    return 0.0


@inlined
def eval_escaped(lt, li, d):
    k = lt.kind[li]
    if k == ENVIRONMENT:
        return _env.env_eval(lt.params, lt.iparams, li, lt.aux, d)
    if k == SUN:
        return _sun.eval_escaped(lt.params, lt.iparams, li, d)
    if k == CONSTANT:
        return _env.constant_eval(lt.params, li)
    return ZERO3


@inlined
def pdf_escaped(lt, li, d):
    k = lt.kind[li]
    if k == ENVIRONMENT:
        return _env.env_pdf(lt.params, lt.iparams, li, lt.aux, d)
    if k == SUN:
        return _sun.pdf_escaped(lt.params, lt.iparams, li, d)
    if k == CONSTANT:
        return INV_4PI
    return 0.0


@inlined
def mesh_pdf_hit(lt, li, o, d, t, local_tri):
    if lt.kind[li] != MESH:
        return 0.0
    return _mesh.pdf_hit_triangle(lt.iparams, li, lt.aux, o, d, t, local_tri)


@inlined
def mesh_eval(lt, li, d, local_tri):
    """Per-triangle radiance of an emitter triangle (its value at the UV centroid if textured)."""
    if lt.kind[li] != MESH:
        return ZERO3
    return _mesh.eval_triangle(lt.iparams, li, lt.aux, d, local_tri)


@inlined
def emitter_of_prim(lt, prim):
    """(mesh light index, local triangle index) of scene primitive ``prim``; (−1, −1) if it emits
    nothing."""
    if prim < 0 or prim >= lt.prim_light.shape[0]:
        return -1, -1
    return lt.prim_light[prim], lt.prim_local[prim]


@inlined
def select(lt, p, u):
    return _sel.select(lt, p, u)


@inlined
def select_prob(lt, p, li):
    return _sel.select_prob(lt, p, li)
