"""Cameras from Blender's image-plane corners (``Camera.view_frame``), perspective or orthographic.

The frame corners (camera space, order top-right, bottom-right, bottom-left, top-left) already carry
sensor fit, shift and aspect, so a film position (s, t) ∈ [0, 1]² (s to the right, t downwards,
pixel (0, 0) at the top-left) maps bilinearly onto the frame. The camera looks down its local −Z.
Thin-lens depth of field focuses on the plane z = −focus_distance (camera space).
"""
from __future__ import annotations

import numpy as np

from .mathutil import norm, normalize, scale_rows
from .sampling.warp import square_to_disk_concentric
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

    def film_to_camera(self, st: np.ndarray) -> np.ndarray:
        tr, br, bl, tl = self.frame
        # tl + s·(tr − tl) + t·(bl − tl) as one (n, 2) @ (2, 3) product (no (n, 1) broadcasting)
        return st @ np.stack([tr - tl, bl - tl]) + tl

    def generate_rays(self, st: np.ndarray, lens_u: np.ndarray | None = None):
        """Film positions (n, 2) → world rays (o, d unit, tmin, tmax), all float64."""
        p = self.film_to_camera(st)
        n = p.shape[0]
        if self.kind == "orthographic":
            o_cam = np.concatenate([p[:, :2], np.zeros((n, 1))], axis=1)
            d_cam = np.tile([0.0, 0.0, -1.0], (n, 1))
        else:
            o_cam = np.zeros((n, 3))
            d_cam = normalize(p)
        cos_axis = np.maximum(-d_cam[:, 2], 1e-12)
        if self.aperture_radius > 0 and self.focus_distance > 0 and lens_u is not None:
            focus = o_cam + d_cam * (self.focus_distance / cos_axis)[:, None]
            lens = self._sample_aperture(lens_u) * self.aperture_radius
            o_cam = o_cam + np.concatenate([lens, np.zeros((n, 1))], axis=1)
            d_cam = normalize(focus - o_cam)
            cos_axis = np.maximum(-d_cam[:, 2], 1e-12)
        o = o_cam @ self.to_world[:3, :3].T + self._origin
        d_world = d_cam @ self._rot.T
        # Clip distances are measured along the view axis, in world units along the ray.
        axis_scale = norm(d_world)
        d = scale_rows(1.0 / np.where(axis_scale > 0, axis_scale, 1.0), d_world)
        tmin = self.clip_start / cos_axis * axis_scale
        tmax = np.where(np.isfinite(self.clip_end), self.clip_end / cos_axis * axis_scale, np.inf)
        return o, d, tmin, tmax

    def _sample_aperture(self, u: np.ndarray) -> np.ndarray:
        if self.blades < 3:
            xy = square_to_disk_concentric(u)
        else:
            # Uniform point in a regular polygon with corners on the unit circle (as Cycles):
            # pick one of the equal triangles (centre, corner k, corner k+1), then a point in it.
            k = np.minimum((u[:, 0] * self.blades).astype(np.int64), self.blades - 1)
            u0 = u[:, 0] * self.blades - k
            a = np.sqrt(u0)
            b = u[:, 1]
            step = 2 * np.pi / self.blades
            c0 = np.stack([np.cos(k * step + self.rotation), np.sin(k * step + self.rotation)], 1)
            c1 = np.stack([np.cos((k + 1) * step + self.rotation), np.sin((k + 1) * step + self.rotation)], 1)
            xy = a[:, None] * ((1 - b)[:, None] * c0 + b[:, None] * c1)
        xy[:, 1] *= self.ratio
        return xy


def parse_camera(node: Node) -> Camera:
    node.require_object()
    kind = node.string("type", choices=("perspective", "orthographic"))
    to_world = node.matrix4("to_world")
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
        focus = dof.number("focus_distance", lo=0, lo_open=True)
        aperture = dof.number("aperture_radius", lo=0)
        blades = dof.integer("blades", 0, lo=0, hi=64)
        rotation = dof.number("rotation", 0.0)
        ratio = dof.number("ratio", 1.0, lo=0, lo_open=True)
        dof.finish()
    node.finish()
    return Camera(kind, to_world, frame, clip_start, clip_end, focus, aperture, blades, rotation, ratio)


def _corner(node: Node) -> np.ndarray:
    from .scene.reader import check_vector
    return check_vector(node.value, 3, node.path, node.ctx)
