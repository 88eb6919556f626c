"""Wavefront unidirectional path tracer with next-event estimation and MIS (power heuristic):
the orchestration. The per-lane work is compiled (``backend/kernels/integrator.py``, whose
docstring describes one bounce); this module builds the typed tables once per scene and runs the
bounce loop of a work item over queues: camera rays → [embree intersect → shade → embree
occluded → add unblocked light] per bounce.

A work item is a set of pixels × a range of sample indices; lane i is sample ``sample0 + i % spp``
of pixel ``pixels[i // spp]``. Random numbers are counter-based (kernels/rng.py), keyed by
(seed, pixel, sample, dimension) — the layered walks included (a sub-stream per bounce) — so an
image does not depend on how the work is cut.
"""
from __future__ import annotations

import threading

import numpy as np

from . import stats
from .caustics import plan_caustics
from .geometry.accel import NO_TIMES
from .kernels import integrator as ki
from .kernels import materials as km
from .kernels.camera import camera_rays, camera_vector
from .kernels.caustics import P_SUPPORT, trace_photons
from .kernels.item_loop import ONE_SEGMENT, STOPPED, TRACED_SEGMENT, WHOLE_ITEM, run_item, start_lanes
from .kernels.layered import batch as layered_batch
from .kernels.layered.table import H_MAXV, H_PDF, H_TRANS, LOBES
from .kernels.lights.table import build_light_table
from .kernels.params import ParamPacker
from .kernels.sampler import SAMPLERS
from .kernels.soup import shading_rows
from .kernels.trace import RAYHIT_WORDS
from .kernels.workitems import (FilmColumns, Lanes, QueuedEmission, RayQueue, SceneTables, ShadowRays,
                                WalkScratch)
from .layered.stack_table import StackBuilder
from .passes import NO_LANES, PassLayout
from .render_settings import kernel_values
from .scene.links import CAMERA, NO_RECEIVER
from .visibility import RAY_BITS, Visibility

#: Path segments whose sampling dimensions come from the stratified (Sobol) sampler; deeper ones
#: use the hashed numbers. Measured (benchmarks/sampler_depth.py, Cornell box 48², 3 seeds):
#: Sobol on the first hit only gives the error of Sobol everywhere (diffuse spheres, 64 spp:
#: RMSE 0.0382 vs 0.0382, independent 0.0487; gold + glass: 0.297 vs 0.303, independent 0.369)
#: while each further stratified bounce costs ~130 ns per lane (3 scrambled 2-D slots).
STRATIFIED_BOUNCES = 1

#: Up to this many light-sampled lights, next-event estimation at an analytic material samples
#: every light (one shadow ray each) instead of picking one: the variance of the pick goes, at
#: the cost of more light samples and shadow rays per vertex. Measured on the peer benchmark's IES
#: + directional-area-light room (96², 16 spp, 8 seeds): image variance 3008 -> 1655.
ALL_LIGHTS_MAX = 4

#: Layered continuations defer their MIS pdf (kernels/integrator.py ``defer_pdf``) in scenes
#: with up to this many lights that light sampling competes for (the queue of emission waiting
#: for such pdfs holds a row per lane and light: 48 bytes each).
DEFER_MAX_LIGHTS = 8


class _Queue:
    """Ray state of the lanes of one bounce (structure of arrays, capacity n)."""

    def __init__(self, n: int, deferred: bool):
        self.slot = np.empty(n, np.int64)
        self.key = np.empty(n, np.uint64)
        self.o = np.empty((n, 3))
        self.d = np.empty((n, 3))
        self.o32 = np.empty((n, 3), np.float32)
        self.d32 = np.empty((n, 3), np.float32)
        self.beta = np.empty((n, 3))
        self.pdf = np.empty(n)
        self.delta = np.empty(n, np.uint8)   # how the ray's vertex was lit (kernels VIA_*)
        self.rtype = np.empty(n, np.uint8)   # the ray's type (scene/links.py bits)
        self.recv = np.empty(n, np.uint8)    # the receiver set of the vertex it left
        # Deferred MIS pdfs of layered continuations (kernels/integrator.py DFR_*): 120 bytes a
        # lane where a scene has layered stacks, one unused row otherwise.
        self.dfr = np.empty((n if deferred else 1, ki.DFR_COLUMNS))

    def outputs(self) -> RayQueue:
        return RayQueue(self.slot, self.key, self.o, self.d, self.o32, self.d32, self.beta, self.pdf,
                        self.delta, self.rtype, self.recv, self.dfr)


class _Scratch:
    """Per-thread working arrays of ``render`` (two ray queues, the shadow-ray queue, the camera
    rays' tmax, the layered walks' scratch), kept between work items: fresh arrays of this size
    (~310 bytes a lane, 20 MB for an item of 2^16 lanes; with deferred layered pdfs 240 bytes
    more and 48 a queued light) are new pages every item, and the page
    faults cost 5-7 % of the render (perf, Cornell box). Grown when an item has more lanes."""

    def __init__(self, n: int, walk_capacity: int, shadows_per_lane: int, deferred: bool, queue_per_lane: int):
        self.n = n
        self.queues = (_Queue(n, deferred), _Queue(n, deferred))
        # Emission queued behind deferred layered pdfs (kernels/integrator.py ``_light_hit``).
        q = n * queue_per_lane if deferred else 1
        self.queued_at = np.empty((q, 2), np.int64)
        self.queued = np.empty((q, 4))
        self.tmax32 = np.empty(n, np.float32)
        self.lane_time = np.empty(n, np.float32)       # shutter time of each lane (motion blur)
        m = n * shadows_per_lane
        self.sh_slot = np.empty(m, np.int64)
        self.sh_o32 = np.empty((m, 3), np.float32)
        self.sh_d32 = np.empty((m, 3), np.float32)
        self.sh_t32 = np.empty(m, np.float32)
        self.sh_c = np.empty((m, 3))
        self.sh_mask = np.empty(m, np.int64)
        self.walk = WalkScratch(*layered_batch.scratch(walk_capacity))
        # The compiled bounce loop's (kernels/item_loop.py): hits, shadow-ray times and answers,
        # embree's ray block, the loop's state.
        self.prim = np.empty(n, np.int32)
        self.t_hit = np.empty(n, np.float32)           # hit distances where Python traced (run_item)
        self.b1 = np.empty(n, np.float32)
        self.b2 = np.empty(n, np.float32)
        self.times = np.empty(n, np.float32)
        self.sh_time = np.empty(m, np.float32)
        self.blocked = np.empty(m, np.int32)
        self.rayhit = np.empty(RAYHIT_WORDS, np.float32)
        self.state = np.zeros(8, np.int64)
        self.shadows = ShadowRays(self.sh_slot, self.sh_o32, self.sh_d32, self.sh_t32, self.sh_c, self.sh_mask,
                                  self.sh_time, self.blocked)
        self.queued_emission = QueuedEmission(self.queued_at, self.queued)


class RenderInterrupted(Exception):
    """``PathTracer.render`` stopped between two bounces because ``interrupt()`` returned true."""


class PathTracer:
    #: Optional callable checked before every bounce of ``render``; when it returns true the work
    #: item is abandoned (RenderInterrupted). The viewport session sets it so that an edit does
    #: not wait for a whole work item.
    interrupt = None
    #: uint8[1] that another thread may set non-zero to the same end, read by the compiled
    #: bounce loop before every bounce (the session's restart flag); None: never.
    stop_flag = None
    _never = np.zeros(1, np.uint8)

    def __init__(self, scene, accel):
        self.scene = scene
        self.accel = accel
        self.soup = soup = scene.soup
        s = scene.settings
        self.max_segments = s.max_bounces + 2
        self.lights = list(scene.lights)
        packer = ParamPacker()
        stacks = StackBuilder(packer)
        self.materials = build_material_table(scene.materials, packer, stacks)
        # Tabulated stacks take more light samples (kernels/integrator.py TABLE_NEE): room for them.
        self._nee_factor = ki.TABLE_NEE if bool((self.materials.kind == km.TABULATED).any()) else 1
        # Next-event estimation never samples a constant world: BSDF sampling is the better
        # strategy for it everywhere (exact for a Lambertian surface: zero variance, as in
        # Cycles), and its escaped rays then keep MIS weight 1 (selection probability 0).
        powers = [float(l.power()) if l.light_sampled else 0.0 for l in self.lights]
        self.light_table = build_light_table(self.lights, packer, scene.radius, s.light_selection,
                                             powers=powers)
        self.textures = packer.table()
        # Layered stacks: their table, and the walks' scratch size (records of two walks).
        self.stacks = stacks.table(self.textures)
        self.walk_capacity = int(max(self.stacks.head[:, H_MAXV].max(), 2))
        has_lights = any(pw > 0 for pw in powers)
        mesh_light = self.lights.index(scene.mesh_light) if scene.mesh_light is not None else -1
        emitter = np.full(max(soup.count, 1), -1, np.int32)
        if scene.mesh_light is not None:
            emitter[scene.mesh_light.triangle_ids] = np.arange(scene.mesh_light.triangle_ids.size)
        count = soup.count
        rows, irows = shading_rows(soup.vertices, soup.normals, soup.uvs, soup.geo_normal, soup.tangent,
                                   soup.material, emitter[:count])
        # Motion blur: the moving triangles' corners (and normals) at each time step, one row of
        # 9 per triangle; the lanes' shutter times (camera_rays writes them) reach embree and
        # the shading of moving triangles. No motion: empty tables, no times.
        self.motion = soup.motion is not None or scene.camera.motion_delta.shape[0] > 0
        if soup.motion is not None:
            mv = np.ascontiguousarray(np.stack(soup.motion).reshape(len(soup.motion), -1, 9), np.float32)
            mn = np.ascontiguousarray(np.stack(soup.motion_normals).reshape(mv.shape), np.float32) \
                if soup.motion_normals is not None else np.zeros((1, 1, 9), np.float32)
        else:
            mv = mn = np.zeros((1, 1, 9), np.float32)
        self.geometry = ki.Geometry(rows, irows,
                                    np.ascontiguousarray(soup.holdout, bool) if count else np.zeros(1, bool),
                                    soup.normals is not None, soup.uvs is not None,
                                    soup.moving_start if soup.motion is not None else max(count, 1), mv, mn)
        # How many lights next-event estimation samples at once at an analytic material's vertex
        # (0: it picks one): every one with local selection (the table's flag: 2 or more lights)
        # and at most ALL_LIGHTS_MAX of them.
        n_sampled = int(self.light_table.sel_active.size)
        nee_all = n_sampled if self.light_table.local_selection and n_sampled <= ALL_LIGHTS_MAX else 0
        # Ray visibility, light and shadow linking: tables, and the embree-side filters.
        self.vis = Visibility(scene, self.lights, mesh_light, self.light_table)
        # A layered continuation's MIS pdf is estimated when its ray finds a light that light
        # sampling competes for, not for every continuation (kernels/integrator.py ``defer_pdf``)
        # — unless a light-sampled light fills every direction (an environment map): then
        # nearly every escaped ray needs it, and estimating it with the vertex's other pdf
        # shares a walk. The emission waiting for such a pdf is queued: at most one row per
        # light-sampled light and shadow-linked light a ray can find; with more than
        # DEFER_MAX_LIGHTS of them the queue would cost more memory than deferring saves.
        # The closed-form "lobes" pdf costs about as much as deferring it (measured: the one-sphere
        # renders of 1-3 slabs took the same CPU with and without deferral), so only stacks with
        # an estimated pdf defer (a transmissive stack's transmissions may take the approximate one).
        self.queue_per_lane = sum(pw > 0 for pw in powers) + int(self.vis.shadow_linked.size)
        head = self.stacks.head[:len(stacks.stacks)]
        estimated_pdf = bool(np.any((head[:, H_PDF] != LOBES) | (head[:, H_TRANS] > 0.0)))
        defer_pdf = estimated_pdf and self.queue_per_lane <= DEFER_MAX_LIGHTS and not any(
            l.fills_sphere and pw > 0 for l, pw in zip(self.lights, powers))
        # Caustics light traced where the scene allows it (backend/caustics.py), and the path
        # tracer's share of them dropped (kernels/integrator.py CAUSTIC_CHAIN).
        self.caustics = plan_caustics(scene, self)
        # Settings the kernels take as they are come from the table (backend/render_settings.py:
        # rr_depth, clamp, glossy_light_samples); the rest are derived here.
        self.settings = ki.Settings(
            seed=np.uint64(s.seed), max_segments=self.max_segments,
            transparent=bool(scene.transparent), has_lights=has_lights, mesh_light=mesh_light,
            hittable=np.array([i for i, l in enumerate(self.lights) if l.is_hittable], np.int64),
            infinite=np.array([i for i, l in enumerate(self.lights) if l.is_infinite], np.int64),
            visible_camera=np.array([bool(getattr(l, "visible_camera", l.is_infinite)) for l in self.lights]
                                    or [False]),
            sampler=SAMPLERS[s.sampler], stratified_bounces=STRATIFIED_BOUNCES, nee_all=nee_all,
            defer_pdf=defer_pdf, probed=self._probed_lights(mesh_light),
            caustic_light=self.caustics.light, caustic_plain=self.caustics.plain,
            caustic_caster=self.caustics.caster,
            **kernel_values(s), **self.vis.kernel_fields())
        self.camera = camera_vector(scene.camera)
        self.camera_motion = np.ascontiguousarray(scene.camera.motion_delta, np.float64)
        if self.motion and (self.vis.filter_shadows or self.vis.skip_hits):
            scene.warnings.append("motion blur with ray visibility, light or shadow linking filters: "
                                  "the filtered rays see moving objects where they are when the shutter opens")
        self.passes = getattr(scene, "passes", None)
        if self.passes is not None and not self.passes.active:
            self.passes = None
        self.pass_params = self._pass_params(scene.camera)
        self.filter = scene.pixel_filter.tables()
        # Which bounces need their hits filtered: the camera's, the others' (ray types).
        lacking = int(np.bitwise_or.reduce(~self.vis.tri_vis & RAY_BITS)) if self.vis.skip_hits else 0
        self.skip_camera = bool(lacking & CAMERA)
        self.skip_indirect = bool(lacking & ~CAMERA)
        self._local = threading.local()      # per-thread _Scratch (threads share one tracer)

    def _probed_lights(self, mesh_light: int) -> np.ndarray:
        """Per light, whether smooth glass and a coated kind's smooth top connect their mirror
        direction to it (kernels/integrator.py ``_probe_reflection``): lights rays can hit that do
        not fill the sphere; an empty array where there is none or where visibility or linking
        filters rays."""
        probed = np.array([(l.is_hittable or l.is_infinite) and not l.fills_sphere for l in self.lights], np.bool_)
        if mesh_light >= 0:
            probed[mesh_light] = False
        if not probed.any() or self.vis.gated or self.vis.filter_shadows or self.vis.skip_hits:
            return np.zeros(0, np.bool_)
        return probed

    def _scratch(self, n: int) -> _Scratch:
        sc = getattr(self._local, "scratch", None)
        if sc is None or sc.n < n:
            # Shadow rays per lane: next-event estimation's (glossy_light_samples per light at a glossy
            # vertex), one per light the mirror of smooth glass or a coated kind's top (its
            # direction or one from its sharp lobe) can meet, and one dedicated ray per light
            # with shadow linking (kernels/integrator.py).
            st = self.settings
            per_lane = (max(1, st.nee_all) * st.glossy_light_samples * self._nee_factor
                        + int(st.probed.sum()) + int(self.vis.shadow_linked.size))
            sc = self._local.scratch = _Scratch(n, self.walk_capacity, per_lane, self.settings.defer_pdf,
                                                self.queue_per_lane)
        return sc

    def set_camera(self, camera) -> None:
        """Render the next work items through another camera (a viewport session's view moved;
        nothing else depends on the camera)."""
        self.scene.camera = camera
        self.camera = camera_vector(camera)
        self.caustics = plan_caustics(self.scene, self)
        self.settings = self.settings._replace(caustic_light=self.caustics.light,
                                               caustic_plain=self.caustics.plain,
                                               caustic_caster=self.caustics.caster)
        self.camera_motion = np.ascontiguousarray(camera.motion_delta, np.float64)
        self.pass_params = self._pass_params(camera)

    def _pass_params(self, camera):
        """The data passes' kernel table (backend/passes.py); an inactive one when none is asked
        for (the kernel then never touches the pass columns)."""
        layout = self.passes if self.passes is not None else PassLayout()
        return layout.params(camera, self.soup, self.scene.materials, self.soup.object_pass,
                             getattr(self.scene, "origin", (0.0, 0.0, 0.0)), self.soup.object_uv)

    # ------------------------------------------------------------------ work item
    def render(self, pixels: np.ndarray, spp: int, rng: np.random.Generator, sample0: int = 0) -> dict:
        """``spp`` samples (indices sample0 …) in each of ``pixels`` (flat, row 0 = top).
        Returns the per-lane samples (lane i: sample i % spp of pixel i // spp) for
        ``FilmAccumulator.add``. ``rng`` is not used (every random number is counter-based)."""
        scene = self.scene
        W, H = scene.width, scene.height
        pixels = np.ascontiguousarray(pixels, np.int64)
        P = pixels.size
        n = P * spp
        L = np.empty((n, 3))          # zeroed by start_lanes (compiled, without the GIL)
        albedo = np.empty((n, 3))
        normal = np.empty((n, 3))
        alpha = np.empty(n)
        # Data passes: a column per requested channel, none (and no allocation) otherwise.
        aux = self.passes.lane_array(n) if self.passes is not None else NO_LANES
        sc = self._scratch(n)
        cur, nxt = sc.queues
        tmax32 = sc.tmax32
        lane_time = sc.lane_time[:n] if self.motion else NO_TIMES
        camera_rays(self.camera, self.camera_motion, self.filter, W, H, self.settings.seed,
                    self.settings.sampler, Lanes(pixels, spp, sample0, lane_time),
                    RayQueue(*(a[:n] for a in cur.outputs())), tmax32[:n])
        # Camera rays: emission seen directly gets weight 1 (VIA_DELTA); light linking does not
        # apply to them (Cycles).
        start_lanes(cur.outputs(), n, ki.VIA_DELTA, CAMERA, NO_RECEIVER, sc.walk,
                    FilmColumns(L, albedo, normal, alpha, aux))
        lc = sc.walk.counters
        counts = np.zeros(5, np.int64)
        rays = self._bounce_loop(sc, Lanes(pixels, spp, sample0, lane_time),
                                 FilmColumns(L, albedo, normal, alpha, aux), counts, n)
        if lc[2]:
            stats.add("layered_walk_cap_hits", int(lc[2]))
        # Per-lane samples: the film adds them in sample order (kernels/film.py).
        out = {"lanes": (L, albedo, normal, alpha), "spp": spp, "rays": rays}
        if self.caustics.active:
            out["caustics"], photon_rays = self._photons(sc, pixels, spp, sample0)
            out["rays"] += photon_rays
        if self.passes is not None:
            out["passes"] = aux
        return out

    def _bounce_loop(self, sc, lanes, film, counts, n) -> int:
        """The item's bounce loop (kernels/item_loop.py ``run_item``): in one compiled call; with
        shadow-ray filters (backend/visibility.py), one call per segment and the shadow rays
        here; where rays must pass objects hidden from them, embree is reached through
        embreex's own queries or a benchmark records the rays, each segment's rays traced here
        too (``_trace_segment``) and shaded by the same call."""
        queries = self.accel.queries
        trace_here = (queries.direct is None or self.accel.recorder is not None
                      or self.skip_camera or self.skip_indirect)
        if trace_here:
            mode = TRACED_SEGMENT
            embree = (0, 0, 0, 0, sc.rayhit)           # unused: run_item traces nothing
            hits = (sc.tmax32, sc.prim, sc.b1, sc.b2, sc.times, sc.t_hit)
        else:
            if not queries.direct.committed:
                queries.commit()
            mode = ONE_SEGMENT if self.vis.filter_shadows else WHOLE_ITEM
            embree = (queries._intersect_fn, queries._occluded_fn, queries.direct.handle, queries.offset1,
                      sc.rayhit)
            hits = (sc.tmax32, sc.prim, sc.b1, sc.b2, sc.times, sc.tmax32)
        L = film.L
        queues = [q.outputs() for q in sc.queues]
        tables = self.tables()
        stop = self.stop_flag if self.stop_flag is not None else self._never
        state = sc.state
        state[:] = 0
        state[1] = n
        killed = deferred = 0
        rays = 0           # every ray of the item (returned)
        uncounted = 0      # those the main accelerator's own queries did not count
        while True:
            if self.interrupt is not None and self.interrupt():
                raise RenderInterrupted
            if trace_here:
                rays += self._trace_segment(sc, queues[0], int(state[0]), int(state[1]), lanes.time)
            run_item(tables, lanes, queues[0], queues[1], sc.shadows, sc.walk, sc.queued_emission, film,
                     embree, hits, mode, stop, counts, state)
            killed += int(state[3])
            deferred += int(state[4])
            rays += int(state[5])
            uncounted += int(state[5])
            if state[6] == STOPPED:
                raise RenderInterrupted
            if state[7]:
                queues.reverse()                  # the next rays are in the other queue
            ns = int(state[2])
            if ns:                                # the shadow rays of one segment, traced here
                if self.vis.filter_shadows:
                    blocked = self.vis.occluded(sc.sh_o32[:ns], sc.sh_d32[:ns], sc.sh_t32[:ns], sc.sh_mask[:ns])
                    uncounted += ns
                else:
                    blocked = self.accel.occluded32(sc.sh_o32[:ns], sc.sh_d32[:ns], sc.sh_t32[:ns],
                                                    lanes.time[sc.sh_slot[:ns]] if self.motion else NO_TIMES)
                rays += ns
                ki.add_unoccluded(sc.sh_slot[:ns], sc.sh_c[:ns], blocked, L)
            if mode == WHOLE_ITEM or state[1] == 0 or state[0] >= self.max_segments:
                break
            state[3:] = 0
        self.accel.rays_traced += uncounted
        self._count(killed, deferred)
        return rays

    def _photons(self, sc, pixels, spp: int, sample0: int) -> tuple:
        """The item's share of the caustic photons (kernels/caustics.py): caustic_photons per
        camera sample, keyed by the item's first pixel and first sample (so the same for any
        worker count). Returns ((photons, flat pixel indices, RGB splats), rays traced)."""
        # at least one per item (rounded up): the path tracer leaves these paths to the photons
        n = int(np.ceil(self.scene.settings.caustic_photons * pixels.size * spp))
        if n == 0:
            return (0, np.zeros(0, np.int64), np.zeros((0, 3))), 0
        plan = self.caustics
        side = int(plan.tables.proj[P_SUPPORT]) + 2
        # room for the usual splats (measured on the demo: 2.8 per photon); more resumes the kernel
        room = max(2 * side * n, 4 * side * side)
        pix = np.empty(room, np.int64)
        rgb = np.empty((room, 3))
        q = self.accel.queries
        if not q.direct.committed:
            q.commit()
        embree = (q._intersect_fn, q._occluded_fn, q.direct.handle, q.offset1, sc.rayhit)
        counts = np.zeros(3, np.int64)
        pixel0 = int(pixels[0]) if pixels.size else 0
        parts, rays, j = [], 0, 0
        while j < n:                     # more than once only where splats overflow the buffers
            trace_photons(self.tables(), plan.tables, embree, pixel0, int(sample0), j, n, pix, rgb, counts)
            k = int(counts[0])
            parts.append((pix[:k].copy(), rgb[:k].copy()))
            rays += int(counts[1])
            j = int(counts[2])
        self.accel.rays_traced += rays
        if len(parts) == 1:
            return (n, *parts[0]), rays
        return (n, np.concatenate([a for a, _ in parts]), np.concatenate([b for _, b in parts])), rays

    def _trace_segment(self, sc, cur, segment: int, active: int, lane_time) -> int:
        """The closest hits of this segment's rays, traced here into the loop's hit arrays (for
        ``TRACED_SEGMENT``): past the objects hidden from each ray type where the scene has them
        (backend/visibility.py re-traces those rays), and with the rays' own limits kept, since
        shading sees them too."""
        o32, d32 = cur.o32[:active], cur.d32[:active]
        t_in = sc.tmax32[:active] if segment == 0 else np.full(active, 3e38, np.float32)
        skip = self.skip_camera if segment == 0 else self.skip_indirect
        # embree writes each hit's distance into the tmax array it is given
        t_ray = t_in.copy() if skip else t_in
        times = lane_time[cur.slot[:active]] if self.motion else NO_TIMES
        prim, t, b1, b2 = self.accel.intersect32(o32, d32, t_in, times)
        if skip:
            t_in = t_ray
            prim, t, b1, b2 = self.vis.skip_hidden(self.accel, o32, d32, t_in, cur.rtype[:active],
                                                   prim, t, b1, b2)
        sc.tmax32[:active] = t_in
        sc.t_hit[:active] = t
        sc.prim[:active] = prim
        sc.b1[:active] = b1
        sc.b2[:active] = b2
        return active

    def tables(self) -> SceneTables:
        """The scene's tables as the kernels take them (built per call: an edit in the viewport
        session replaces some of them, the data passes' with the camera)."""
        return SceneTables(self.geometry, self.materials, self.textures, self.light_table, self.settings,
                           self.pass_params, self.stacks)

    def _count(self, killed: int, deferred: int) -> None:
        if killed:
            stats.add("paths_nonfinite_killed", killed)
        if deferred:
            stats.add("layered_pdfs_deferred", deferred)   # estimated when a ray found a light


def build_material_table(materials, packer, stacks=None):
    return km.build_material_table(materials, packer, stacks)
