"""Cameras from Blender's image-plane corners (``Camera.view_frame``), perspective or orthographic.

The frame corners (camera space, order top-right, bottom-right, bottom-left, top-left) already carry
sensor fit, shift and aspect, so a film position (s, t) ∈ [0, 1]² (s to the right, t downwards,
pixel (0, 0) at the top-left) maps bilinearly onto the frame. The camera looks down its local −Z.
Thin-lens depth of field focuses on the plane z = −focus_distance (camera space).
"""
from __future__ import annotations

import numpy as np

from .limits import MAX_COORDINATE
from .scene.reader import Node


class Camera:
    def __init__(self, kind: str, to_world: np.ndarray, frame: np.ndarray, clip_start: float = 0.0,
                 clip_end: float = np.inf, focus_distance: float = 0.0, aperture_radius: float = 0.0,
                 blades: int = 0, rotation_deg: float = 0.0, ratio: float = 1.0):
        self.kind = kind
        self.to_world = np.asarray(to_world, dtype=np.float64)
        self.frame = np.asarray(frame, dtype=np.float64)  # (4, 3): tr, br, bl, tl
        self.clip_start = clip_start
        self.clip_end = clip_end
        self.focus_distance = focus_distance
        self.aperture_radius = aperture_radius
        self.blades = blades
        self.rotation = np.radians(rotation_deg)
        self.ratio = ratio
        rot = self.to_world[:3, :3]
        # Directions transform with the rotation part; normalise afterwards (matrix may scale).
        self._rot = rot
        self._origin = self.to_world[:3, 3]
        #: Motion blur: the rigid change from ``to_world`` to the camera's transform at K equally
        #: spaced times over the shutter, M_k · to_world⁻¹, as (K, 12) rows of 3 × 4 (empty: the
        #: camera does not move; kernels/camera.py applies it to each ray).
        self.motion_delta = np.zeros((0, 12))

    def set_motion(self, matrices: list) -> None:
        inv = np.linalg.inv(self.to_world)
        self.motion_delta = np.array([(np.asarray(m, np.float64) @ inv)[:3].ravel() for m in matrices])

    def generate_rays(self, st: np.ndarray, lens_u: np.ndarray | None = None):
        """Film positions (n, 2) → world rays (o, d unit, tmin, tmax), all float64.

        The ray model lives once, per lane, in backend/kernels/camera.py (the renderer's camera
        kernel); this array form serves tests and tools."""
        from .kernels.camera import camera_vector, generate_batch
        st = np.ascontiguousarray(st, dtype=np.float64)
        n = st.shape[0]
        use_lens = lens_u is not None
        lu = np.ascontiguousarray(lens_u, dtype=np.float64) if use_lens else np.zeros((1, 2))
        o, d = np.empty((n, 3)), np.empty((n, 3))
        tmin, tmax = np.empty(n), np.empty(n)
        generate_batch(camera_vector(self), st, lu, use_lens, o, d, tmin, tmax)
        return o, d, tmin, tmax


def parse_camera(node: Node) -> Camera:
    node.require_object()
    kind = node.string("type", choices=("perspective", "orthographic"))
    to_world = node.matrix4("to_world")
    motion = node.motion()
    frame_node = node.child("frame")
    corners = frame_node.items()
    if len(corners) != 4:
        raise frame_node.fail(f"expected 4 corners (top-right, bottom-right, bottom-left, top-left), got {len(corners)}")
    frame = np.array([_corner(c) for c in corners])
    tr, br, bl, tl = frame
    if np.linalg.norm(np.cross(tr - tl, bl - tl)) <= 0:
        raise frame_node.fail("the frame corners are degenerate (zero image area)")
    if kind == "perspective" and np.any(frame[:, 2] >= 0):
        raise frame_node.fail("perspective frame corners must lie in front of the camera (z < 0)")
    clip_start = node.number("clip_start", 0.0, lo=0)
    clip_end = node.number("clip_end", 1e30, lo=0, lo_open=True)
    if clip_end <= clip_start:
        raise node.fail(f"must be greater than clip_start ({clip_start:g})", "clip_end")
    focus = aperture = 0.0
    blades = 0
    rotation = 0.0
    ratio = 1.0
    dof = node.optional_child("dof")
    if dof is not None:
        focus = dof.number("focus_distance", lo=0, lo_open=True, hi=MAX_COORDINATE)
        aperture = dof.number("aperture_radius", lo=0, hi=MAX_COORDINATE)
        blades = dof.integer("blades", 0, lo=0, hi=64)
        if blades in (1, 2):
            # Blender accepts them and Cycles draws a round aperture: so does Lamina, but a
            # hand-written 1 or 2 is more likely a mistake than a wish for a circle.
            node.ctx.warn(dof.sub("blades"), f"{blades} blade(s) make a round aperture, as 0 does "
                                             f"(a polygonal aperture needs at least 3)")
        rotation = dof.number("rotation", 0.0)
        ratio = dof.number("ratio", 1.0, lo=0, lo_open=True, hi=1000.0)
        dof.finish()
    node.finish()
    camera = Camera(kind, to_world, frame, clip_start, clip_end, focus, aperture, blades, rotation, ratio)
    if motion is not None:
        camera.set_motion(motion)
    return camera


def _corner(node: Node) -> np.ndarray:
    from .scene.reader import check_vector
    return check_vector(node.value, 3, node.path, node.ctx, -MAX_COORDINATE, MAX_COORDINATE)
