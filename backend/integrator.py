"""Wavefront unidirectional path tracer with next-event estimation and MIS (power heuristic).

One call renders a *work item*: a set of pixels × a range of sample indices, all paths as rows of
arrays. Each bounce: intersect every live ray (embree), add emission from lights the ray passed
(lights are transparent, as in Cycles) and from emissive surfaces/the environment with MIS
weights, then per material group (a loop over the materials present, not over rays): bind the
BSDF once, sample a light (selection ∝ power) and evaluate the BSDF for it, sample the BSDF for
the next direction. Shadow rays of all groups are traced in one embree call. Russian roulette
after ``rr_depth`` bounces; dead lanes are compacted away.

Path length: ``max_bounces`` has Cycles' meaning (0 = direct lighting only), so a path has at most
``max_bounces + 2`` segments (camera → ... → light).

Precision: shading state is float64 (see materials/base.py); rays go to embree as float32.
"""
from __future__ import annotations

import numpy as np

from . import stats
from .geometry.accel import offset_origin
from .materials.base import ShadingContext
from .lights.selection import build_selector
from .mathutil import Frame, abs_max3, dot, max3, norm, normalize, scale_rows, take_rows

SHADOW_EPS = 1e-4  # shorten shadow rays by this fraction so they do not hit the light's own surface


def power_heuristic(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a²/(a²+b²) with 0/0 → 0 (the reference implementation's last bug was this 0/0)."""
    a2 = a * a
    den = a2 + b * b
    return np.where(den > 0, a2 / np.where(den > 0, den, 1.0), 0.0)


def valid_reflection_normal(wi: np.ndarray, ns: np.ndarray, ng: np.ndarray) -> np.ndarray:
    """Bend interpolated shading normals so that the mirror direction of wi stays above the
    geometric surface (the idea of Cycles' ensure_valid_specular_reflection, own derivation).

    On coarse smooth-shaded meshes the mirror reflection about ns can point below the triangle;
    such a ray would enter the object and the energy is lost (dark rims on mirrors). Where that
    happens, the reflection is lifted to just above the geometric plane (cosine ``threshold``) and
    the normal replaced by the half vector of wi and the lifted reflection, keeping ns's side.
    """
    wi_ng = dot(wi, ng)
    side = np.where(wi_ng >= 0, 1.0, -1.0)         # ng·side is the geometric normal on wi's side
    cos_i = np.abs(wi_ng)
    c = dot(wi, ns)
    # r·ng·side for the mirror direction r = 2c·ns − wi, without forming r on every lane
    r_ng = side * (2.0 * c * dot(ns, ng) - wi_ng)
    threshold = np.minimum(0.9 * cos_i, 0.01)
    bad = (r_ng < threshold) & (c * side > 0)
    if not bad.any():
        return ns
    idx = np.flatnonzero(bad)
    ngw = ng[idx] * side[idx, None]
    r = 2.0 * c[idx, None] * ns[idx] - wi[idx]
    r_b = r + (threshold[idx] - dot(r, ngw))[:, None] * ngw
    h = normalize(wi[idx] + normalize(r_b))
    out = ns.copy()
    out[idx] = h * np.sign(c[idx])[:, None]
    return out


class PathTracer:
    def __init__(self, scene, accel):
        self.scene = scene
        self.accel = accel
        self.soup = scene.soup
        s = scene.settings
        self.max_segments = s.max_bounces + 2
        self.rr_depth = s.rr_depth
        self.clamp = s.clamp
        self.lights = list(scene.lights)
        # Selection ∝ power; zero-power lights are never picked (lights/selection.py).
        self.selector = build_selector(self.lights, s.light_selection, scene.radius)
        self.hittable = [i for i, l in enumerate(self.lights) if l.is_hittable]
        self.infinite = [i for i, l in enumerate(self.lights) if l.is_infinite]
        self.mesh_light_index = None
        self.emitter_of_tri = None
        if scene.mesh_light is not None:
            self.mesh_light_index = self.lights.index(scene.mesh_light)
            self.emitter_of_tri = np.full(self.soup.count, -1, np.int64)
            self.emitter_of_tri[scene.mesh_light.triangle_ids] = np.arange(scene.mesh_light.triangle_ids.size)
        self.emissive_material = np.array([getattr(m, "emission", None) is not None for m in scene.materials] or [False])
        self.any_hidden = bool(self.soup.count) and not bool(self.soup.camera_visible.all())
        self.any_emissive = bool(self.emissive_material.any())
        self.two_sided = np.array([m.two_sided for m in scene.materials] or [True])
        # Sort key of each triangle's material: int16 makes numpy's stable argsort a radix sort
        # (10x faster than the int32 timsort on 65k lanes).
        key_type = np.int16 if len(scene.materials) < 2 ** 15 else np.int64
        self.material_key = self.soup.material.astype(key_type)
        self.tables = _ShadingTables(self.soup)

    def select_prob(self, light_index: int, o: np.ndarray) -> np.ndarray:
        """Probability that next-event estimation at points o picks this light (for MIS)."""
        if self.selector is None:
            return np.zeros(o.shape[0])
        return self.selector.prob_at(o, light_index)

    # ------------------------------------------------------------------ work item
    def render(self, pixels: np.ndarray, spp: int, rng: np.random.Generator) -> dict:
        """Render ``spp`` samples in each of ``pixels`` (flat indices, row 0 = top). Per-pixel sums."""
        scene = self.scene
        W, H = scene.width, scene.height
        P = pixels.size
        n = P * spp
        lane_pixel = np.repeat(pixels, spp)
        px = (lane_pixel % W).astype(np.float64)
        py = (lane_pixel // W).astype(np.float64)
        off = scene.pixel_filter.sample(rng.random((n, 2)))
        st = np.stack([(px + 0.5 + off[:, 0]) / W, (py + 0.5 + off[:, 1]) / H], axis=1)
        lens_u = rng.random((n, 2)) if scene.camera.aperture_radius > 0 else None
        o, d, tmin, tmax = scene.camera.generate_rays(st, lens_u)
        o = o + d * tmin[:, None]
        tmax = tmax - tmin

        L = np.zeros((n, 3))
        alpha = np.zeros(n)       # coverage: 1 where the camera ray hit a (non-holdout) surface
        albedo = np.zeros((n, 3))
        normal = np.zeros((n, 3))
        lane = np.arange(n)
        beta = np.ones((n, 3))
        prev_pdf = np.zeros(n)
        prev_delta = np.ones(n, dtype=bool)   # camera rays: emission seen directly gets weight 1

        for segment in range(self.max_segments):
            if lane.size == 0:
                break
            camera_ray = segment == 0
            prim, t, b1, b2 = self.accel.intersect(o, d, tmax)
            if camera_ray and self.any_hidden:
                prim, t, b1, b2 = self._skip_hidden(o, d, tmax, prim, t, b1, b2)
            t_surf = np.where(prim >= 0, t, np.inf)
            self._add_light_hits(L, lane, o, d, np.minimum(t_surf, tmax), beta, prev_pdf, prev_delta, segment)
            miss = prim < 0
            if miss.any() and self.infinite and not (camera_ray and self.scene.transparent):
                self._add_escaped(L, lane[miss], o[miss], d[miss], beta[miss], prev_pdf[miss], prev_delta[miss], segment)
            hit = ~miss
            if camera_ray:
                # Holdout objects are black, transparent holes for camera rays (as in Cycles);
                # they still cast shadows and show in reflections.
                hit[hit] = ~self.soup.holdout[prim[hit]]
                alpha[lane[hit]] = 1.0
            idx = self._hits_by_material(hit, prim)
            if idx.size == 0:
                break
            lane, d, beta, prev_pdf, prev_delta, prim, b1, b2 = (
                take_rows(x, idx) for x in (lane, d, beta, prev_pdf, prev_delta, prim, b1, b2))
            if self.any_emissive:   # o and t are used by surface emission only
                o, t = take_rows(o, idx), take_rows(t, idx)
            si = self._surface(prim, b1, b2, -d)
            if self.any_emissive:
                self._add_surface_emission(L, lane, o, d, t, si, beta, prev_pdf, prev_delta, segment)
            last = segment == self.max_segments - 1
            lane, o, d, beta, prev_pdf, prev_delta = self._scatter(
                L, albedo if camera_ray else None, normal if camera_ray else None,
                lane, si, beta, rng, segment, do_continue=not last)
            tmax = np.full(lane.size, np.inf)

        bad = ~np.isfinite(abs_max3(L))      # NaN and ±inf in any channel
        if bad.any():
            stats.add("samples_nonfinite_dropped", int(bad.sum()))
            L[bad] = 0.0
        return {
            "sum": _pixel_sums(L, P, spp),
            "sum_sq": _pixel_sums(L * L, P, spp),
            "albedo": _pixel_sums(albedo, P, spp),
            "normal": _pixel_sums(normal, P, spp),
            "count": np.full(P, spp, dtype=np.int64),
            "alpha": alpha.reshape(P, spp).sum(axis=1),
        }

    # ------------------------------------------------------------------ geometry
    def _skip_hidden(self, o, d, tmax, prim, t, b1, b2, max_layers: int = 16):
        """Camera rays pass through objects with visible_camera = false (bounded re-tracing)."""
        prim, t, b1, b2 = prim.copy(), t.copy(), b1.copy(), b2.copy()
        t_base = np.zeros(prim.size)
        for _ in range(max_layers):
            hidden = prim >= 0
            hidden[hidden] = ~self.soup.camera_visible[prim[hidden]]
            if not hidden.any():
                break
            idx = np.nonzero(hidden)[0]
            p_hit = o[idx] + d[idx] * (t_base[idx] + t[idx])[:, None]
            ng = self.soup.geo_normal[prim[idx]]
            start = offset_origin(p_hit, ng, d[idx])
            adv = dot(start - o[idx], d[idx])
            p2, t2, u2, v2 = self.accel.intersect(start, d[idx], tmax[idx] - adv)
            prim[idx], t[idx], b1[idx], b2[idx] = p2, t2, u2, v2
            t_base[idx] = adv
        return prim, t + t_base, b1, b2

    def _hits_by_material(self, hit: np.ndarray, prim: np.ndarray) -> np.ndarray:
        """Indices of the hit lanes, grouped by material (stable, so lane order is kept within a
        group): gathering with these compacts and sorts in one pass, and every material is then a
        contiguous slice in _scatter."""
        idx = np.flatnonzero(hit)
        return idx[np.argsort(self.material_key[prim[idx]], kind="stable")]

    def _surface(self, prim, b1, b2, wi):
        soup, tab = self.soup, self.tables
        # Hit points from barycentrics in float64 (not o + t·d): accurate to the vertex precision.
        p = tab.interpolate(tab.position, prim, b1, b2)
        ng = take_rows(soup.geo_normal, prim)
        if tab.normal is not None:
            ns = tab.interpolate(tab.normal, prim, b1, b2)
            length = norm(ns)
            degenerate = length == 0
            ns = scale_rows(1.0 / np.where(degenerate, 1.0, length), ns)
            if degenerate.any():
                ns[degenerate] = ng[degenerate]
        else:
            ns = ng.copy()
        if tab.uv is not None:
            uv = tab.interpolate(tab.uv, prim, b1, b2)
        else:
            uv = np.zeros((prim.size, 2))
        return {"p": p, "ng": ng, "ns": ns, "uv": uv, "tangent": take_rows(soup.tangent, prim),
                "material": take_rows(soup.material, prim), "prim": prim, "wi": wi}

    # ------------------------------------------------------------------ emission
    def _mis_weight_for_hit(self, light_index, pdf_light_sa, prev_pdf, prev_delta, o):
        if prev_delta.all():
            return np.ones(prev_delta.shape[0])
        p_l = self.select_prob(light_index, o) * pdf_light_sa
        return np.where(prev_delta, 1.0, power_heuristic(prev_pdf, p_l))

    def _clamp(self, contrib: np.ndarray, segment: int) -> np.ndarray:
        if self.clamp > 0 and segment > 0:
            m = max3(contrib)
            scale = np.where(m > self.clamp, self.clamp / np.where(m > self.clamp, m, 1.0), 1.0)  # no overflow for tiny m
            return scale_rows(scale, contrib)
        return contrib

    def _add_light_hits(self, L, lane, o, d, t_limit, beta, prev_pdf, prev_delta, segment):
        for li in self.hittable:
            light = self.lights[li]
            if segment == 0 and not getattr(light, "visible_camera", False):
                continue
            t = light.intersect(o, d, t_limit)
            idx = np.flatnonzero(np.isfinite(t))
            if idx.size == 0:
                continue
            o_h, d_h, t_h = take_rows(o, idx), take_rows(d, idx), t[idx]
            Le = light.eval_hit(o_h, d_h, t_h)
            w = self._mis_weight_for_hit(li, light.pdf_hit(o_h, d_h, t_h), prev_pdf[idx], prev_delta[idx], o_h)
            # One ray per lane: the lanes are unique, so a gathered sum written back is exact
            # (and several times faster than np.add.at).
            rows = lane[idx]
            L[rows] = take_rows(L, rows) + self._clamp(scale_rows(w, take_rows(beta, idx) * Le), segment)

    def _add_escaped(self, L, lane, o, d, beta, prev_pdf, prev_delta, segment):
        for li in self.infinite:
            light = self.lights[li]
            if segment == 0 and not getattr(light, "visible_camera", True):
                continue   # e.g. a sun disk hidden from the camera (Blender's default for lights)
            Le = light.eval_escaped(d)
            w = self._mis_weight_for_hit(li, light.pdf_escaped(d), prev_pdf, prev_delta, o)
            L[lane] += self._clamp(beta * Le * w[:, None], segment)

    def _add_surface_emission(self, L, lane, o, d, t, si, beta, prev_pdf, prev_delta, segment):
        emits = self.emissive_material[si["material"]]
        # Emission shaders emit from both faces, as in Cycles (measured with Cycles 5.0.1).
        m = emits
        if not m.any():
            return
        idx = np.nonzero(m)[0]
        Le = np.zeros((idx.size, 3))
        mats = si["material"][idx]
        for mi in np.unique(mats):
            g = mats == mi
            value = self.scene.materials[mi].emission.bind(si["uv"][idx[g]])
            Le[g] = np.broadcast_to(np.asarray(value, dtype=np.float64).reshape(-1, 3), (int(g.sum()), 3))
        w = np.ones(idx.size)
        if self.mesh_light_index is not None:
            light = self.lights[self.mesh_light_index]
            local = self.emitter_of_tri[si["prim"][idx]]
            ok = local >= 0
            pdf = np.zeros(idx.size)
            if ok.any():
                pdf[ok] = light.pdf_hit_triangle(o[idx[ok]], d[idx[ok]], t[idx[ok]], local[ok])
            w = self._mis_weight_for_hit(self.mesh_light_index, pdf, prev_pdf[idx], prev_delta[idx], o[idx])
        L[lane[idx]] += self._clamp(beta[idx] * Le * w[:, None], segment)

    # ------------------------------------------------------------------ scattering
    def _scatter(self, L, albedo_aov, normal_aov, lane, si, beta, rng, segment, do_continue):
        # The lanes arrive sorted by material (_hits_by_material): every material group is a
        # contiguous slice, so the per-group work below uses views instead of gathered copies.
        mats = si["material"]
        n = lane.size
        wi, ng, ns = si["wi"], si["ng"], si["ns"]
        two_sided = self.two_sided[mats]
        # Reflection-only materials are seen from both sides: turn the normals towards the viewer,
        # and where the interpolated shading normal still faces away, fall back to the geometric one.
        if normal_aov is not None:
            normal_aov[lane] = ns
        back = two_sided & (dot(wi, ng) < 0)
        if back.any():
            flip = np.where(back, -1.0, 1.0)
            ng = scale_rows(flip, ng)
            ns = scale_rows(flip, ns)
        bad_shading = two_sided & (dot(wi, ns) <= 0)
        if bad_shading.any():
            ns = np.where(bad_shading[:, None], ng, ns)   # a new array: si["ns"] stays as it was
        if self.soup.normals is not None:
            ns = valid_reflection_normal(wi, ns, ng)
        frame = Frame.from_normal_tangent(ns, si["tangent"])
        wi_local = frame.to_local(wi)
        p = si["p"]

        new_dir = np.zeros((n, 3))
        new_beta = np.zeros((n, 3))
        new_pdf = np.zeros(n)
        new_delta = np.zeros(n, dtype=bool)
        can_nee = self.selector is not None and segment + 1 < self.max_segments
        if can_nee:
            # Light samples for every lane at once; the BSDF is evaluated per material group below.
            wi_w, dist, value, lpdf, is_delta, sel_p = self._sample_lights(p, rng)
            wo_nee = frame.to_local(wi_w)
            live = (max3(value) > 0) & ((dot(wi_w, ng) * wo_nee[:, 2]) > 0)
            f_nee = np.zeros((n, 3))
            bsdf_pdf = np.zeros(n)
            any_rough_light = not is_delta.all()

        bounds = np.concatenate([[0], np.flatnonzero(np.diff(mats)) + 1, [n]])
        for a, b in zip(bounds[:-1], bounds[1:]):
            g = slice(int(a), int(b))
            material = self.scene.materials[mats[a]]
            bsdf = material.bind(ShadingContext(si["uv"][g]))
            wi_g = wi_local[g]
            # Stochastic BSDFs (layered) estimate their albedo with a walk of their own; at a
            # camera hit the continuation sample below is that walk already (its reflected weight
            # averages to the directional albedo at the viewing angle), so only the last segment
            # pays for a separate estimate. Measured: 17 % of a one-slab sphere render.
            albedo_from_sample = albedo_aov is not None and do_continue and getattr(bsdf, "stochastic", False)
            if albedo_aov is not None and not albedo_from_sample:
                albedo_aov[lane[g]] = np.broadcast_to(np.asarray(bsdf.albedo(), dtype=np.float64), (b - a, 3))
            smp = None
            if can_nee and not bsdf.delta_only:
                # The light connection (on lanes whose light sample carries light) and, if the
                # path goes on, the continuation sample in one call: stochastic BSDFs share walks.
                f_nee[g], pdf_g, smp = bsdf.nee_and_sample(wi_g, wo_nee[g], live[g], rng,
                                                           any_rough_light, do_continue)
                if any_rough_light:
                    bsdf_pdf[g] = pdf_g
            if do_continue:
                if smp is None:
                    smp = bsdf.sample(wi_g, rng)
                d_world = Frame(frame.s[g], frame.t[g], frame.n[g]).to_world(smp.wo)
                new_dir[g] = d_world
                # Leak guard: the sampled side must agree for the shading and the geometric normal.
                ok = (dot(d_world, ng[g]) * smp.wo[:, 2]) > 0
                new_beta[g] = scale_rows(ok, beta[g] * smp.weight)
                new_pdf[g] = smp.pdf
                new_delta[g] = smp.delta
                if albedo_from_sample:
                    reflected = (smp.wo[:, 2] * wi_g[:, 2]) > 0
                    albedo_aov[lane[g]] = np.where(reflected[:, None], smp.weight, 0.0)

        if can_nee:
            w = np.where(is_delta, 1.0, power_heuristic(sel_p * lpdf, bsdf_pdf)) / sel_p
            contrib = scale_rows(w * live, beta * f_nee * value)
            keep = np.flatnonzero(max3(contrib) > 0)
            if keep.size:
                wi_keep = take_rows(wi_w, keep)
                origin = offset_origin(take_rows(p, keep), take_rows(ng, keep), wi_keep)
                d_keep = dist[keep]
                tmax = np.where(np.isfinite(d_keep), d_keep * (1.0 - SHADOW_EPS), np.inf)
                lit = keep[~self.accel.occluded(origin, wi_keep, tmax)]
                # One shadow ray per lane and bounce: lane indices are unique, a gathered sum
                # written back is exact.
                rows = take_rows(lane, lit)
                L[rows] = take_rows(L, rows) + self._clamp(take_rows(contrib, lit), segment)

        if not do_continue:
            return lane[:0], p[:0], new_dir[:0], new_beta[:0], new_pdf[:0], new_delta[:0]
        # Russian roulette (unbiased: survivors are divided by the survival probability).
        peak = max3(new_beta)
        if segment + 1 >= self.rr_depth:
            q = np.minimum(peak, 1.0)
            survive = rng.random(n) < q
            new_beta = scale_rows(np.where(survive, 1.0 / np.where(q > 0, q, 1.0), 0.0), new_beta)
            peak = np.where(survive, peak, 0.0)
        finite = np.isfinite(peak)
        if not finite.all():
            stats.add("paths_nonfinite_killed", int((~finite).sum()))
        alive = np.flatnonzero((peak > 0) & finite)
        new_dir = take_rows(new_dir, alive)
        origin = offset_origin(take_rows(p, alive), take_rows(ng, alive), new_dir)
        return (take_rows(lane, alive), origin, new_dir, take_rows(new_beta, alive),
                take_rows(new_pdf, alive), take_rows(new_delta, alive))

    def _sample_lights(self, p, rng):
        """Pick a light per lane (∝ power) and sample it: world directions, distances,
        radiance/pdf values, solid-angle pdfs, delta flags and selection probabilities."""
        m = p.shape[0]
        u_light = rng.random((m, 2))
        if len(self.lights) == 1:
            light = self.lights[0]
            ls = light.sample(p, u_light)
            return ls.wi, ls.dist, ls.value, ls.pdf, np.full(m, light.is_delta), np.ones(m)
        li_of, sel_p = self.selector.sample_at(p, rng.random(m))
        wi_w = np.zeros((m, 3))
        dist = np.zeros(m)
        value = np.zeros((m, 3))
        lpdf = np.zeros(m)
        is_delta = np.zeros(m, dtype=bool)
        for li in np.unique(li_of):
            k = li_of == li
            light = self.lights[li]
            ls = light.sample(p[k], u_light[k])
            wi_w[k], dist[k], value[k], lpdf[k] = ls.wi, ls.dist, ls.value, ls.pdf
            is_delta[k] = light.is_delta
        return wi_w, dist, value, lpdf, is_delta, sel_p


def _pixel_sums(x: np.ndarray, pixels: int, spp: int) -> np.ndarray:
    """Per-pixel sums of (pixels·spp, 3) lane values, lanes of a pixel adjacent. einsum instead
    of .sum(axis=1): 5x faster for this (P, spp, 3) layout (measured, numpy 1.26)."""
    return np.einsum("psc->pc", x.reshape(pixels, spp, 3))


class _ShadingTables:
    """Per-triangle float64 tables for interpolating surface attributes at hit points.

    Each row holds the value at corner 0 followed by the differences to corners 1 and 2, so an
    attribute at barycentrics (b1, b2) is row[0:k] + b1·row[k:2k] + b2·row[2k:3k]: one row
    gather per hit and no (n, 3, 3) temporaries (the einsum over gathered corners was 4x slower).
    """

    def __init__(self, soup):
        self.position = self._table(soup.vertices64)
        self.normal = None if soup.normals64 is None else self._table(soup.normals64)
        self.uv = None if soup.uvs64 is None else self._table(soup.uvs64)

    @staticmethod
    def _table(corners: np.ndarray) -> np.ndarray:
        c0 = corners[:, 0]
        return np.ascontiguousarray(np.concatenate([c0, corners[:, 1] - c0, corners[:, 2] - c0], axis=1))

    @staticmethod
    def interpolate(table: np.ndarray, prim: np.ndarray, b1: np.ndarray, b2: np.ndarray) -> np.ndarray:
        k = table.shape[1] // 3
        rows = take_rows(table, prim)
        out = np.empty((prim.size, k))
        for c in range(k):   # per component: 1-D operations, no (n, 1) broadcasting
            out[:, c] = rows[:, c] + b1 * rows[:, k + c] + b2 * rows[:, 2 * k + c]
        return out
