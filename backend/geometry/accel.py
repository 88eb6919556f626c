"""World-space triangle soup and the embree acceleration structure.

Instances are flattened: every object's mesh is transformed to world space once at load, and all
triangles go into one embree geometry, so ``primID`` is a global triangle index. (embreex has no
instancing API; flattening costs memory only for heavily instanced scenes.)

Ray offsetting: new rays start at the hit point moved along the geometric normal, to the side the
ray leaves towards, by ``offset_scale(p)`` — a multiple of the float32 spacing at the point's
magnitude. Hit points are recomputed in float64 from barycentrics (not o + t·d), so the offset only
has to cover float32 vertex/traversal error: no self-intersection acne, and leaks only through gaps
smaller than ~1e-5 relative to the scene coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mathutil import abs_max3, add_scaled, dot

# Offset in units of the coordinate magnitude: 2^-16 ≈ 1.5e-5, i.e. ~128 float32 ulps.
OFFSET_RELATIVE = 2.0 ** -16
OFFSET_ABSOLUTE = 1e-7  # metres, for points near the origin


@dataclass
class TriangleSoup:
    """All triangles of the scene in world space plus their shading attributes."""

    vertices: np.ndarray          # (T, 3, 3) float32 world positions (what embree traces)
    normals: np.ndarray | None    # (T, 3, 3) float32 world shading normals per corner, or None
    uvs: np.ndarray | None        # (T, 3, 2) float32, or None
    material: np.ndarray          # (T,) int32 global material index
    object_id: np.ndarray         # (T,) int32 index into the scene's objects
    camera_visible: np.ndarray    # (T,) bool
    holdout: np.ndarray = None    # (T,) bool: camera rays see a transparent hole (alpha 0, black)
    geo_normal: np.ndarray = None   # (T, 3) float64 unit geometric normal (CCW winding)
    tangent: np.ndarray = None      # (T, 3) float64 unit dP/du (UV tangent), zeros where undefined
    area: np.ndarray = None         # (T,) float64
    object_pass: list = None        # each object's pass index (the Object Index pass)
    object_uv: list = None          # whether each object's mesh has a UV map (the UV pass)
    # Per object (object_id indexes them; scene/links.py): names, ray-type bits, the receiver
    # list of an emissive object (light linking). Defaults: every ray sees every object.
    object_names: list = None
    object_vis: np.ndarray = None
    object_receivers: list = None
    # Motion blur (scene/loader.py): the last M triangles move; their corners, and shading normals
    # where the soup has normals, at K ≥ 2 equally spaced times over the shutter, each
    # (M, 3, 3) float32 (``vertices`` holds them at the frame's instant). None: nothing moves.
    motion: list = None
    motion_normals: list = None

    def __post_init__(self):
        if self.holdout is None:
            self.holdout = np.zeros(self.vertices.shape[0], dtype=bool)
        if self.object_names is None:
            from ..scene.links import ALL_RAYS, CAMERA
            n = int(self.object_id.max()) + 1 if self.object_id.size else 0
            hidden = np.zeros(n, bool)
            hidden[self.object_id[~np.asarray(self.camera_visible, bool)]] = True
            self.object_names = [f"object {i}" for i in range(n)]
            self.object_vis = np.where(hidden, ALL_RAYS & ~CAMERA, ALL_RAYS).astype(np.uint8)
            self.object_receivers = [None] * n
        from ..kernels.soup import triangle_frames
        self.geo_normal, self.tangent, self.area = triangle_frames(self.vertices, self.uvs)

    @property
    def count(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def moving_start(self) -> int:
        """Index of the first moving triangle (``count`` when nothing moves)."""
        return self.count - (self.motion[0].shape[0] if self.motion else 0)


def offset_scale(p: np.ndarray) -> np.ndarray:
    return OFFSET_ABSOLUTE + OFFSET_RELATIVE * abs_max3(p)


def offset_origin(p: np.ndarray, ng: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Move p off the surface along ±ng to the side direction d points to."""
    side = np.where(dot(ng, d) >= 0, 1.0, -1.0)
    return add_scaled(p, side * offset_scale(p), ng)


NO_TIMES = np.zeros(0, np.float32)      # rays without a time (no motion blur): time 0


class EmbreeQueries:
    """Closest-hit and occlusion queries on one embree scene: compiled loops (kernels/trace.py)
    over the scene geometry/embree_lib.py builds (rays may carry a time: ``moving`` triangles are
    traced where they are at that time), or embreex's own ``run`` where that route is not
    available (then without motion)."""

    def __init__(self, vertices: np.ndarray, moving: list | None = None):
        import threading

        from .embree_lib import query_addresses, triangle_scene
        vertices = np.ascontiguousarray(vertices, dtype=np.float32)
        self._lock = threading.Lock()
        self.direct = triangle_scene(vertices, moving)
        if self.direct is not None:
            self.scene = self.direct.scene
            self._intersect_fn, self._occluded_fn = query_addresses()
            self.offset1 = vertices.shape[0] - (moving[0].shape[0] if moving else 0)
            return
        if moving:
            from ..errors import LaminaError
            raise LaminaError("motion blur needs direct access to embree's library, which was not "
                              "found next to embreex on this system: render without motion blur")
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
        self.scene = rtcs.EmbreeScene()
        if vertices.shape[0]:
            TriangleMesh(self.scene, vertices)

    @property
    def committed(self) -> bool:
        return bool(self.scene.is_committed)

    def commit(self) -> None:
        """Build the BVH now (else the first query does)."""
        with self._lock:
            if self.direct is not None:
                self.direct.commit()
            elif not self.scene.is_committed:
                self.scene.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32))

    def intersect(self, o32, d32, tmax32, time32=NO_TIMES):
        """(prim int32 −1 = miss, t float32 (= tmax32, overwritten), b1, b2 float32)."""
        if self.direct is None:
            res = self.scene.run(o32, d32, dists=tmax32, output=True)
            return res["primID"], res["tfar"], res["u"], res["v"]
        if not self.direct.committed:
            self.commit()
        from ..kernels.trace import RAYHIT_WORDS, intersect_rays
        n = o32.shape[0]
        prim = np.empty(n, np.int32)
        b1 = np.empty(n, np.float32)
        b2 = np.empty(n, np.float32)
        intersect_rays(self._intersect_fn, self.direct.handle, self.offset1, np.empty(RAYHIT_WORDS, np.float32),
                       o32, d32, tmax32, time32, prim, b1, b2)
        return prim, tmax32, b1, b2

    def occluded(self, o32, d32, tmax32, time32=NO_TIMES) -> np.ndarray:
        """int32: −1 where the segment (0, tmax) is free, 0 where something blocks it."""
        if self.direct is None:
            return np.asarray(self.scene.run(o32, d32, dists=tmax32, query="OCCLUDED"))
        if not self.direct.committed:
            self.commit()
        from ..kernels.trace import RAYHIT_WORDS, occluded_rays
        blocked = np.empty(o32.shape[0], np.int32)
        occluded_rays(self._occluded_fn, self.direct.handle, np.empty(RAYHIT_WORDS, np.float32),
                      o32, d32, tmax32, time32, blocked)
        return blocked


class Accelerator:
    """embree scene over a TriangleSoup. Built per process (embree objects do not pickle)."""

    def __init__(self, soup: TriangleSoup):
        self.soup = soup
        self.queries = EmbreeQueries(soup.vertices, getattr(soup, "motion", None))
        self.rays_traced = 0
        #: Set to a list to record every traced batch (benchmarks re-trace the render's own rays).
        self.recorder: list | None = None

    def commit(self) -> None:
        self.queries.commit()

    def intersect(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray | None = None):
        """Closest hits. Returns (prim (n,) int64 with -1 = miss, t (n,), b1 (n,), b2 (n,))."""
        n = o.shape[0]
        if n == 0:
            z = np.zeros(0)
            return np.zeros(0, np.int64), z, z, z
        o32 = np.ascontiguousarray(o, dtype=np.float32)
        d32 = np.ascontiguousarray(d, dtype=np.float32)
        dists = np.full(n, 3e38, np.float32) if tmax is None else \
            np.ascontiguousarray(np.minimum(tmax, 3e38), dtype=np.float32)
        if self.recorder is not None:
            self.recorder.append(("intersect", o32, d32, dists.copy()))
        prim, t, b1, b2 = self.queries.intersect(o32, d32, dists)
        self.rays_traced += n
        return prim.astype(np.int64), t.astype(np.float64), b1.astype(np.float64), b2.astype(np.float64)

    def intersect32(self, o32: np.ndarray, d32: np.ndarray, tmax32: np.ndarray, time32=NO_TIMES):
        """Closest hits of float32 rays as embree returns them: (prim int32 with −1 = miss,
        t float32, b1 float32, b2 float32) — the kernels read these without conversion.
        embree writes each hit's distance into ``tmax32``: keep a copy where the limits are
        needed afterwards."""
        if o32.shape[0] == 0:
            z = np.zeros(0, np.float32)
            return np.zeros(0, np.int32), z, z, z
        if self.recorder is not None:
            # Copies: the integrator's queues are reused between bounces and work items.
            self.recorder.append(("intersect", o32.copy(), d32.copy(), tmax32.copy()))
        res = self.queries.intersect(o32, d32, tmax32, time32)
        self.rays_traced += o32.shape[0]
        return res

    def occluded32(self, o32: np.ndarray, d32: np.ndarray, tmax32: np.ndarray, time32=NO_TIMES) -> np.ndarray:
        """−1 where the float32 segment (0, tmax) is free, else 0 (embree's any-hit query does
        not say which triangle)."""
        if o32.shape[0] == 0:
            return np.zeros(0, np.int32)
        if self.recorder is not None:
            self.recorder.append(("occluded", o32.copy(), d32.copy(), tmax32.copy()))
        res = self.queries.occluded(o32, d32, tmax32, time32)
        self.rays_traced += o32.shape[0]
        return res

    def occluded(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray) -> np.ndarray:
        """True where something lies on the segment (0, tmax)."""
        n = o.shape[0]
        if n == 0:
            return np.zeros(0, bool)
        o32 = np.ascontiguousarray(o, dtype=np.float32)
        d32 = np.ascontiguousarray(d, dtype=np.float32)
        dists = np.ascontiguousarray(np.minimum(tmax, 3e38), dtype=np.float32)
        if self.recorder is not None:
            self.recorder.append(("occluded", o32, d32, dists))
        res = self.queries.occluded(o32, d32, dists)
        self.rays_traced += n
        return res != -1


class Occluder:
    """An embree scene over some of the scene's triangles, for shadow rays only (the triangles
    that stop one class of shadow rays: backend/visibility.py). Empty: nothing blocks."""

    def __init__(self, vertices: np.ndarray):
        self._queries = EmbreeQueries(vertices) if vertices.shape[0] else None

    def occluded32(self, o32: np.ndarray, d32: np.ndarray, tmax32: np.ndarray, time32=NO_TIMES) -> np.ndarray:
        """−1 where the segment (0, tmax) is free, else 0."""
        if self._queries is None or o32.shape[0] == 0:
            return np.full(o32.shape[0], -1, np.int32)
        return self._queries.occluded(np.ascontiguousarray(o32), np.ascontiguousarray(d32),
                                      np.ascontiguousarray(tmax32), time32)


def retrace(accel: "Accelerator", batches: list) -> float:
    """Trace recorded batches again with embree alone; returns seconds (benchmarks)."""
    import time
    q = accel.queries
    q.commit()
    t0 = time.perf_counter()
    for kind, o32, d32, dists in batches:
        if kind == "intersect":
            q.intersect(o32, d32, dists.copy())
        else:
            q.occluded(o32, d32, dists.copy())
    return time.perf_counter() - t0
