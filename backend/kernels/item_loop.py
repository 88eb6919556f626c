"""A work item's bounce loop, compiled: trace → shade → trace shadow rays → add what they let
through, segment after segment, without returning to Python (backend/integrator.py sets it up).

Why compiled: with the loop in Python, a render thread took the GIL back between every compiled
call (about 2.5 % of a render's CPU on the Cornell box and the demo, benchmarks/parallel_scaling.py),
which is what bounds a render with many threads: at 2.5 % held, 40 threads at most could run
at once however many cores there are. Here one call renders the item and holds the GIL only to
enter and leave.

The bundles are kernels/workitems.py's named tuples: the scene's tables, the lanes, two ray
queues (the rays of this bounce and of the next, swapped after each), the shadow rays, the film
columns, the walks' scratch, the queued emission; embree as (intersect function, occluded
function, scene handle, geometry-1 offset, RTCRayHit scratch); the hits as (tmax32, prim, b1, b2,
time32, t32), the item loop's own arrays (t32: the hit distances where the caller traced; the
tmax32 array itself otherwise, since embree writes them there).

``mode``: WHOLE_ITEM, the item's every segment here; ONE_SEGMENT, shade a single segment and leave
its shadow rays to the caller (scenes whose shadow rays need filters made in Python:
backend/visibility.py); TRACED_SEGMENT, the same for a segment whose rays the caller traced into
the hit arrays (rays that pass objects hidden from them, embree through embreex's own queries, a
benchmark recording the rays: backend/integrator.py). One loop for every case: Python only
traces what the compiled code cannot. ``stop[0]`` non-zero (another thread may set it: the
viewport session's restart) ends the item before the next bounce.

``state`` (int64[8]) in: [segment, active lanes]; out: [segment reached, active lanes,
pending shadow rays, non-finite paths killed (sum), deferred pdfs (sum), rays traced (sum),
STOPPED or DONE, which queue holds the next rays (0: the first)].
"""
from __future__ import annotations

import numpy as np

from .integrator import add_unoccluded, shade
from .jit import kernel
from .trace import intersect_rays, occluded_rays
from .workitems import TracedHits, queue_head


@kernel(nogil=True)
def start_lanes(q, n, delta, rtype, recv, walk, film):
    """The first n lanes of queue ``q`` start their paths (camera_rays wrote their rays): slot i,
    throughput 1, no previous pdf, the given ``delta``, ray type and receiver set; the layered
    walks' scratch as fresh (its counters are per item); the film columns (L, albedo, normal,
    alpha: allocated empty, zeroed here without the GIL) at 0."""
    slot, beta, pdf, dl, rt, rv = q.slot, q.beta, q.pdf, q.delta, q.rtype, q.recv
    for i in range(n):
        slot[i] = i
        beta[i, 0] = 1.0
        beta[i, 1] = 1.0
        beta[i, 2] = 1.0
        pdf[i] = 0.0
        dl[i] = delta
        rt[i] = rtype
        rv[i] = recv
    walk.vertices.fill(0.0)
    walk.stack.fill(0.0)
    walk.stream.fill(0)
    walk.counters.fill(0)
    film.L.fill(0.0)
    film.albedo.fill(0.0)
    film.normal.fill(0.0)
    film.alpha.fill(0.0)


DONE = 0
STOPPED = 1
FAR = np.float32(3e38)
WHOLE_ITEM, ONE_SEGMENT, TRACED_SEGMENT = 0, 1, 2


@kernel(nogil=True)
def run_item(tables, lanes, q0, q1, shadows, walk, queued, film, embree, hits, mode, stop, counts, state):
    S = tables.settings
    lane_time = lanes.time
    segment = state[0]
    active = state[1]
    motion = lane_time.shape[0] > 0
    tmax, prim, b1, b2, tt, t_hit = hits
    fn_hit, fn_occ, scene, offset1, rayhit = embree
    L = film.L
    sh_slot, sh_o32, sh_d32, sh_t32, sh_c = shadows.slot, shadows.o32, shadows.d32, shadows.t32, shadows.c
    sh_time, blocked = shadows.time32, shadows.blocked
    killed = 0
    deferred = 0
    rays = 0
    flip = 0
    status = DONE
    ns = 0
    while segment < S.max_segments and active > 0:
        if stop[0] != 0:
            status = STOPPED
            break
        cur = q1 if flip else q0
        nxt = q0 if flip else q1
        t_in = tmax[:active]
        t_out = t_hit[:active]
        if mode != TRACED_SEGMENT:
            if segment > 0:                 # the camera rays' limits only hold for segment 0
                for i in range(active):
                    tmax[i] = FAR
            times = tt[:active] if motion else tt[:0]
            if motion:
                for i in range(active):
                    times[i] = lane_time[cur.slot[i]]
            intersect_rays(fn_hit, scene, offset1, rayhit, cur.o32[:active], cur.d32[:active], t_in, times,
                           prim[:active], b1[:active], b2[:active])
            rays += active
        for k in range(counts.shape[0]):
            counts[k] = 0
        shade(tables, segment, lanes, queue_head(cur, active),
              TracedHits(t_in, prim[:active], t_out, b1[:active], b2[:active]),
              film, nxt, shadows, walk, queued, counts)
        ns = counts[1]
        killed += counts[3]
        deferred += counts[4]
        active = counts[0]
        flip = 1 - flip
        segment += 1
        if mode != WHOLE_ITEM:
            break
        if ns > 0:
            st = sh_time[:ns] if motion else sh_time[:0]
            if motion:
                for k in range(ns):
                    st[k] = lane_time[sh_slot[k]]
            occluded_rays(fn_occ, scene, rayhit, sh_o32[:ns], sh_d32[:ns], sh_t32[:ns], st, blocked[:ns])
            rays += ns
            add_unoccluded(sh_slot[:ns], sh_c[:ns], blocked[:ns], L)
            ns = 0
    state[0] = segment
    state[1] = active
    state[2] = ns
    state[3] = killed
    state[4] = deferred
    state[5] = rays
    state[6] = status
    state[7] = flip
