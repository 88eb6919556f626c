"""Ray visibility, light linking and shadow linking in the integrator (scene/links.py has the
semantics and the scene fields): the kernels' tables, and the two embree-side filters.

Nothing here runs for a scene without these features (``skip_hits`` and ``filter_shadows``
are false, and the kernels test one flag), so such a scene costs what it cost before.

Closest hits (camera, diffuse, glossy, transmission rays): the ray is traced in the one scene
as usual, and only the lanes whose hit is invisible to their ray type are traced again from just
past that hit, at most ``MAX_LAYERS`` times. The cost is paid only by rays that actually hit a
hidden object, the queues stay one batch (no split by ray type), and the kernels keep the one
global primitive numbering of the one scene.

Shadow rays: embree's OCCLUDED query is any-hit and reports only the geometry, not which
triangle blocked, so a blocker that should be ignored cannot be told apart afterwards (nor what
lies before it). Instead every blocker class gets its own embree scene holding exactly the
triangles that stop it: one per distinct blocker mask (every light without shadow linking
shares one, plus one per shadow-linked light's mask, typically 1-3 scenes), each a subset of the
scene's triangles. Shadow rays are traced against their mask's scene: exact, no re-tracing.
"""
from __future__ import annotations

import numpy as np

from .geometry.accel import Occluder, offset_origin
from .scene.links import ALL_RAYS, ALL_SETS, CAMERA, DIFFUSE, GLOSSY, NO_RECEIVER, SHADOW, TRANSMIT, Links

#: At most this many hidden surfaces are passed per ray; a ray still on a hidden surface after
#: them stops there (a closest hit: shaded as visible; a shadow ray: blocked).
MAX_LAYERS = 16
RAY_BITS = CAMERA | DIFFUSE | GLOSSY | TRANSMIT


def _has_diffuse(material) -> bool:
    """Does a layered stack (or any nested one) have a diffuse interface?"""
    for m in getattr(material, "interfaces", ()) or ():
        if getattr(m, "type_name", "") == "diffuse" or _has_diffuse(m):
            return True
    return False


class Visibility:
    """The tables of one scene. ``kernel_fields()`` gives the ``Settings`` fields from ``track``
    on (kernels/integrator.py documents them)."""

    def __init__(self, scene, lights: list, mesh_light_index: int, light_table):
        soup = scene.soup
        links: Links = scene.links
        n_obj = len(soup.object_names)
        obj_vis = np.asarray(links.object_vis if links is not None else soup.object_vis, np.uint8)
        self.tri_vis = obj_vis[soup.object_id] if soup.count and n_obj else np.full(max(soup.count, 1), ALL_RAYS, np.uint8)
        # Closest hits need filtering where some object hides from some ray type.
        self.skip_hits = bool(soup.count) and bool(((self.tri_vis & RAY_BITS) != RAY_BITS).any())
        n = len(lights)
        light_vis = np.full(max(n, 1), ALL_RAYS, np.uint8)
        light_recv = np.full(max(n, 1), ALL_SETS, np.int64)
        light_shadow = np.full(max(n, 1), ALL_SETS, np.int64)
        if links is not None:
            lamps = len(links.lamp_vis)      # the scene's lamps come first in ``lights``
            light_vis[:lamps] = links.lamp_vis
            light_recv[:lamps] = links.lamp_receivers
            light_shadow[:lamps] = links.lamp_blockers
        ml = scene.mesh_light
        if ml is not None:
            emit_obj = soup.object_id[ml.triangle_ids]
            emit_vis = obj_vis[emit_obj]
            emit_recv = links.object_receivers[emit_obj] if links is not None else np.full(emit_obj.size, ALL_SETS, np.int64)
        else:
            emit_vis = np.full(1, ALL_RAYS, np.uint8)
            emit_recv = np.full(1, ALL_SETS, np.int64)
        self.light_linking = links is not None and links.light_linking
        shadow_linking = links is not None and links.shadow_linking
        # Lights BSDF-sampled rays can hit (not delta) with shadow linking: dedicated rays.
        self.shadow_linked = np.array([i for i in range(n) if light_shadow[i] != ALL_SETS
                                       and (light_table.is_hittable[i] or light_table.is_infinite[i])
                                       and not light_table.is_delta[i]], np.int64)
        vis_gated = bool(((light_vis[:n] & RAY_BITS) != RAY_BITS).any()) or bool(
            (ml is not None) and ((emit_vis & (DIFFUSE | GLOSSY | TRANSMIT)) != (DIFFUSE | GLOSSY | TRANSMIT)).any())
        self.gated = vis_gated or self.light_linking or shadow_linking
        self.track = self.gated or self.skip_hits
        self.tri_recv = (links.receiver_set[soup.object_id] if self.light_linking and soup.count
                         else np.zeros(1, np.uint8)).astype(np.uint8)
        self.tri_block = (links.blocker_set[soup.object_id] if shadow_linking and soup.count
                          else np.zeros(max(soup.count, 1), np.uint8)).astype(np.int64)
        self.filter_shadows = bool(soup.count) and (
            shadow_linking or bool(((self.tri_vis & SHADOW) == 0).any()))
        self.mat_refl = np.array([DIFFUSE if _has_diffuse(m) else GLOSSY for m in scene.materials] or [GLOSSY],
                                 np.uint8)
        self._fields = dict(track=self.track, gated=self.gated, links=self.light_linking,
                            shadow_linked=self.shadow_linked, tri_recv=self.tri_recv,
                            light_vis=light_vis, light_recv=light_recv, light_shadow=light_shadow,
                            emit_vis=emit_vis.astype(np.uint8), emit_recv=np.asarray(emit_recv, np.int64),
                            mat_refl=self.mat_refl)
        self.soup = soup
        # Shadow rays: one embree scene per blocker mask a shadow ray can carry (every light
        # without shadow linking: −1), built here so that render threads only read them.
        self._occluders = {}
        if self.filter_shadows:
            for mask in {ALL_SETS, *(int(m) for m in light_shadow[:n])}:
                keep = ((self.tri_vis & SHADOW) != 0) & (((np.int64(mask) >> self.tri_block) & 1) != 0)
                self._occluders[mask] = Occluder(soup.vertices[keep[:soup.count]])

    def kernel_fields(self) -> dict:
        """The visibility and linking fields of kernels/integrator.py's ``Settings``, by name."""
        return dict(self._fields)

    # ------------------------------------------------------------------ closest hits
    def skip_hidden(self, accel, o32, d32, t_in, rtype, prim, t, b1, b2):
        """Rays pass through objects invisible to their type (bounded re-tracing, see above).
        Returns (prim, t from the original origin, b1, b2)."""
        hidden = prim >= 0
        hidden[hidden] = (self.tri_vis[prim[hidden]] & rtype[hidden]) == 0
        if not hidden.any():
            return prim, t, b1, b2
        prim, t, b1, b2 = prim.copy(), t.astype(np.float64), b1.copy(), b2.copy()
        idx = np.nonzero(hidden)[0]
        o = o32[idx].astype(np.float64)          # the rays' own origins (t is measured from them)
        d = d32[idx].astype(np.float64)
        base = np.zeros(idx.size)                # where the last trace started, along d
        cur_prim, cur_t = prim[idx], t[idx]      # its hit, t from that start
        for _ in range(MAX_LAYERS):
            p_hit = o + d * (base + cur_t)[:, None]
            start = offset_origin(p_hit, self.soup.geo_normal[cur_prim], d)
            adv = np.einsum("ij,ij->i", start - o, d)
            p2, t2, u2, v2 = accel.intersect32(np.ascontiguousarray(start, np.float32),
                                               np.ascontiguousarray(d, np.float32),
                                               np.ascontiguousarray(np.maximum(t_in[idx] - adv, 0), np.float32))
            prim[idx], t[idx], b1[idx], b2[idx] = p2, adv + t2, u2, v2
            again = p2 >= 0
            again[again] = (self.tri_vis[p2[again]] & rtype[idx][again]) == 0
            if not again.any():
                break
            keep = np.nonzero(again)[0]
            idx, o, d, base, cur_prim, cur_t = idx[keep], o[keep], d[keep], adv[keep], p2[keep], t2[keep]
        return prim, t.astype(np.float32), b1, b2

    # ------------------------------------------------------------------ shadow rays
    def occluded(self, o32, d32, t32, mask):
        """OCCLUDED answers (−1 = free) of shadow rays against the triangles that block each:
        one embree scene per distinct blocker mask among the rays (see the module docstring)."""
        first = int(mask[0])
        if (mask == first).all():
            return self._occluders[first].occluded32(o32, d32, t32)
        blocked = np.empty(mask.size, np.int32)
        for m in np.unique(mask):
            idx = np.nonzero(mask == m)[0]
            blocked[idx] = self._occluders[int(m)].occluded32(o32[idx], d32[idx], t32[idx])
        return blocked


__all__ = ["Visibility", "MAX_LAYERS", "NO_RECEIVER"]
