"""What the bounce loop's stages hand each other, by name (the idea of pbrt-v4's wavefront work
items): the scene's tables, the lanes of a work item, the ray queues, the traced hits, the shadow
rays, the film columns, the layered walks' scratch and the emission queued behind deferred pdfs.

Structures of arrays, as named tuples of NumPy arrays: Numba passes them to compiled code as it
passes a tuple (no copy), and the code reads ``queue.beta`` instead of the eleventh of 57
positional parameters. backend/integrator.py builds them; kernels/item_loop.py (``run_item``) and
kernels/integrator.py (``shade``) take them.
"""
from __future__ import annotations

from collections import namedtuple

from .jit import inlined

#: The scene as the kernels read it: triangles for shading (kernels/integrator.py ``Geometry``),
#: materials (kernels/materials.py), textures (kernels/textures.py), lights
#: (kernels/lights/table.py), render settings (kernels/integrator.py ``Settings``), data passes
#: (backend/passes.py) and layered stacks (kernels/layered/table.py).
SceneTables = namedtuple("SceneTables", ["geometry", "materials", "textures", "lights", "settings", "passes",
                                         "stacks"])

#: The lanes of a work item: lane i is sample ``sample0 + i % spp`` of pixel ``pixels[i // spp]``;
#: ``time`` each lane's shutter time (motion blur; empty without).
Lanes = namedtuple("Lanes", ["pixels", "spp", "sample0", "time"])

#: The rays of one bounce, one row per lane (backend/integrator.py ``_Queue`` allocates them): the
#: lane's slot, its path key, the ray in float64 and as traced (float32), the path throughput, the
#: pdf and how the ray's vertex was lit (kernels/integrator.py VIA_*), the ray type and the
#: receiver set of the vertex it left (scene/links.py), and deferred MIS pdfs (DFR_*).
RayQueue = namedtuple("RayQueue", ["slot", "key", "o", "d", "o32", "d32", "beta", "pdf", "delta", "rtype",
                                   "recv", "dfr"])

#: What tracing the rays found: their limit (embree writes the hit distance over it), the
#: triangle hit (−1: none) and its barycentrics; ``t32`` the hit distance the shading reads.
TracedHits = namedtuple("TracedHits", ["tmax32", "prim", "t32", "b1", "b2"])

#: Shadow rays from next-event estimation: the lane they belong to, the ray, its length, the
#: contribution if nothing blocks it, the blocker sets it may pass (light linking), and for the
#: compiled loop's own tracing each ray's shutter time and embree's answer.
ShadowRays = namedtuple("ShadowRays", ["slot", "o32", "d32", "t32", "c", "mask", "time32", "blocked"])

#: The per-lane columns the film receives (radiance, the denoising albedo and normal, alpha) and
#: the data passes' columns (backend/passes.py).
FilmColumns = namedtuple("FilmColumns", ["L", "albedo", "normal", "alpha", "aux"])

#: The layered walks' scratch of one render thread (kernels/layered/batch.py ``scratch``):
#: vertices, bound stack, random-stream state, counters.
WalkScratch = namedtuple("WalkScratch", ["vertices", "stack", "stream", "counters"])

#: Emission found behind a layered continuation whose MIS pdf is deferred (kernels/integrator.py
#: ``_light_hit``): (lane, target) rows and (emission RGB, light density) rows.
QueuedEmission = namedtuple("QueuedEmission", ["at", "values"])


@inlined
def queue_head(q, n):
    """The first n lanes of a ray queue (views, no copy)."""
    return RayQueue(q.slot[:n], q.key[:n], q.o[:n], q.d[:n], q.o32[:n], q.d32[:n], q.beta[:n], q.pdf[:n],
                    q.delta[:n], q.rtype[:n], q.recv[:n], q.dfr[:n])
