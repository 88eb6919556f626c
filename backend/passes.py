"""Data passes (Blender's view-layer passes Depth, Mist, Normal, Position, UV, Object Index and
Material Index): what the scene asks for, where each pass sits in the per-lane arrays, and how the
film turns its sums into images. Cycles' conventions, measured with Blender 5.0.1 (see
tests/blender/test_passes_parity.py):

* written at the first surface a camera ray hits (holdouts and the world write nothing);
* **first-sample passes** — Depth, Position, Object Index, Material Index — hold the value of
  the pixel's sample 0 (never averaged: an index at an object's edge is one index, not a mix,
  and a Position lies on a surface; measured: Cycles' Depth, Position and indices are the same
  at 1, 2 and 16 samples per pixel); Depth of a pixel whose sample 0 hit nothing is 1e10,
  Position 0;
* **averaged passes** — Mist, Normal, UV — are the mean over the pixel's samples, escaped
  samples counting as Mist 1 and as 0 for the others (so an edge pixel's Normal is shorter than
  1, and UV's third channel is the fraction of samples that hit a UV-mapped mesh);
* Depth is the distance along the camera's view axis (perspective and orthographic), Mist's
  distance is the Euclidean distance to the camera (perspective) or along the view axis
  (orthographic), mapped to clamp((d − start) / depth, 0, 1) ^ falloff; Normal (the shading
  normal, turned towards the camera) and Position are in world space.

Nothing is allocated or written when no pass is requested (``PassLayout.active`` false).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .limits import MAX_COORDINATE
from .scene.reader import Node

MAX_PASS_INDEX = 65535     # Blender's pass indices are 16-bit (0 … 32767 in its UI)

#: Pass name in the scene file → (channels, first-sample, EXR/Blender pass name, channel letters).
#: Canonical order: first-sample passes first (the film keeps them apart from the sums).
PASSES = {
    "depth": (1, True, "Depth", "Z"),
    "position": (3, True, "Position", "XYZ"),
    "object_index": (1, True, "Object Index", "X"),
    "material_index": (1, True, "Material Index", "X"),
    "mist": (1, False, "Mist", "Z"),
    "normal": (3, False, "Normal", "XYZ"),
    "uv": (3, False, "UV", "UVA"),
}

DEPTH_ESCAPED = 1.0e10      # Cycles' Depth where nothing was hit (metres)
MIST_ESCAPED = 1.0          # Mist of a sample that hit nothing (fully misted)
FALLOFF = {"linear": 1.0, "quadratic": 2.0, "inverse_quadratic": 0.5}   # Blender's mist falloffs
#: A work item's pass columns when no pass is requested (nothing allocated per item).
NO_LANES = np.zeros((0, 0))

# What the shade kernel reads: lane-array column of every pass (−1: not requested), the mist
# mapping, the camera (position, unit view axis, orthographic?), the rebase offset added to
# Position, and the index tables (object per triangle, pass index per object and per material).
PassParams = namedtuple("PassParams", [
    "active", "depth", "object_index", "material_index", "mist", "normal", "position", "uv",
    "mist_start", "mist_inv_depth", "mist_falloff", "ortho", "cam_pos", "cam_axis", "origin",
    "tri_object", "object_pass", "material_pass", "object_uv"])


class PassLayout:
    """The requested passes and their columns: ``first`` columns (sample 0) then ``summed`` ones."""

    def __init__(self, names=(), mist_start: float = 5.0, mist_depth: float = 25.0,
                 mist_falloff: str = "quadratic"):
        names = set(names)
        self.names = [n for n in PASSES if n in names]
        self.columns: dict[str, int] = {}
        col = 0
        for n in self.names:
            self.columns[n] = col
            col += PASSES[n][0]
        self.width = col
        self.first = sum(PASSES[n][0] for n in self.names if PASSES[n][1])
        self.mist_start = float(mist_start)
        self.mist_depth = float(mist_depth)
        self.mist_falloff = mist_falloff

    @property
    def active(self) -> bool:
        return self.width > 0

    def lane_array(self, n: int) -> np.ndarray:
        """Per-lane values of a work item, preset to what a sample that hits nothing holds."""
        a = np.zeros((n, self.width))
        if "depth" in self.columns:
            a[:, self.columns["depth"]] = DEPTH_ESCAPED
        if "mist" in self.columns:
            a[:, self.columns["mist"]] = MIST_ESCAPED
        return a

    def params(self, camera, soup, materials, object_pass, origin, object_uv=()) -> PassParams:
        """The kernel's table for this scene and camera."""
        col = {n: self.columns.get(n, -1) for n in PASSES}
        rot = np.asarray(camera.to_world, np.float64)[:3, :3]
        axis = -rot[:, 2] / max(np.linalg.norm(rot[:, 2]), 1e-30)    # the camera looks down −Z
        pos = np.asarray(camera.to_world, np.float64)[:3, 3]
        tri_object = soup.object_id if soup.count else np.zeros(1, np.int32)
        mat_pass = np.array([float(getattr(m, "pass_index", 0)) for m in materials] or [0.0])
        obj_pass = np.asarray(list(object_pass or []) or [0.0], np.float64)
        obj_uv = np.asarray(list(object_uv or []) or [False], np.bool_)
        return PassParams(
            self.active, col["depth"], col["object_index"], col["material_index"], col["mist"],
            col["normal"], col["position"], col["uv"],
            self.mist_start, 1.0 / self.mist_depth if self.mist_depth > 0 else 0.0,
            FALLOFF[self.mist_falloff], camera.kind == "orthographic",
            (float(pos[0]), float(pos[1]), float(pos[2])), (float(axis[0]), float(axis[1]), float(axis[2])),
            tuple(float(v) for v in origin), np.ascontiguousarray(tri_object, np.int32), obj_pass,
            np.ascontiguousarray(mat_pass, np.float64), obj_uv)

    def images(self, first: np.ndarray, sums: np.ndarray, count: np.ndarray, height: int, width: int) -> dict:
        """Film arrays → {EXR pass name: (H, W, C) image} in canonical order."""
        out = {}
        c = np.maximum(count, 1)[:, None]
        for n in self.names:
            k, is_first, label, _ = PASSES[n]
            j = self.columns[n]
            if is_first:
                data = first[:, j:j + k]
            else:
                j -= self.first
                data = sums[:, j:j + k] / c
            out[label] = data.reshape(height, width, k)
        return out


def channel_letters() -> dict[str, str]:
    """EXR pass name → channel letters (Blender's)."""
    return {label: letters for _, _, label, letters in PASSES.values()}


def parse_passes(node: Node | None) -> PassLayout:
    """The ``passes`` section: pass name → ``{}`` (or ``true``); ``mist`` takes start, depth and
    falloff (Blender's world mist settings)."""
    if node is None:
        return PassLayout()
    node.require_object()
    names = []
    start, depth, falloff = 5.0, 25.0, "quadratic"
    for name, sub in node.entries():
        if name.startswith("_"):
            continue
        if name not in PASSES:
            raise node.fail(f"unknown pass {name!r} (known: {', '.join(PASSES)})", name)
        if sub.value is True:
            names.append(name)
            continue
        if sub.value is False:
            continue
        sub.require_object()
        if name == "mist":
            start = sub.number("start", start, lo=0, hi=MAX_COORDINATE)
            depth = sub.number("depth", depth, lo=0, hi=MAX_COORDINATE)
            falloff = sub.string("falloff", falloff, choices=tuple(FALLOFF))
        sub.finish()
        names.append(name)
    return PassLayout(names, start, depth, falloff)
