"""A 3D viewport's view → the scene format's camera and film (no bpy: plain matrices).

The region's own matrices are used as they are: ``view_matrix`` (world → view) and
``window_matrix`` (view → clip space, OpenGL conventions: the visible box is NDC [−1, 1]³).
Unprojecting the four corners of the NDC near and far planes gives the image plane of the
region, whatever produced the matrices: a perspective or orthographic view, or the camera view
(Blender builds its window matrix from the camera's lens, sensor fit and shift and from the
view's zoom and pan of the camera frame). So nothing of Blender's projection is re-derived.

* perspective: the corners on the near plane, scaled to z = −1, are the ``frame``; the near and
  far distances are the clip range (measured along the view axis, as the backend does);
* orthographic: the rays start on the near plane (Blender's orthographic views put it *behind*
  the view point, at half the clip end) and run to the far plane; the camera origin is moved to
  the near plane and the frame holds the plane's extent.
"""
from __future__ import annotations

import math

import numpy as np

#: NDC (x, y) of the frame corners in the backend's order: top-right, bottom-right, bottom-left, top-left.
CORNERS = ((1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0))


def _unproject(inverse: np.ndarray, x: float, y: float, z: float) -> np.ndarray:
    h = inverse @ np.array([x, y, z, 1.0])
    return h[:3] / h[3]


def view_camera(view_matrix, window_matrix, perspective: bool) -> dict:
    """The scene file's ``camera`` for a view (no depth of field)."""
    view = np.array(view_matrix, dtype=np.float64).reshape(4, 4)
    inverse = np.linalg.inv(np.array(window_matrix, dtype=np.float64).reshape(4, 4))
    to_world = np.linalg.inv(view)
    # A view matrix is a rigid motion; remove any rounding of its rotation's lengths.
    lengths = np.linalg.norm(to_world[:3, :3], axis=0)
    to_world[:3, :3] /= np.where(lengths > 0, lengths, 1.0)
    near = [_unproject(inverse, x, y, -1.0) for x, y in CORNERS]
    far = [_unproject(inverse, x, y, 1.0) for x, y in CORNERS]
    if perspective:
        frame = [[float(v) for v in p / -p[2]] for p in near]
        clip_start = max(float(-near[0][2]), 0.0)
        clip_end = float(-far[0][2])
        kind = "perspective"
    else:
        z_near, z_far = float(near[0][2]), float(far[0][2])
        shift = np.eye(4)
        shift[2, 3] = z_near
        to_world = to_world @ shift
        frame = [[float(p[0]), float(p[1]), -1.0] for p in near]
        clip_start, clip_end = 0.0, z_near - z_far
        kind = "orthographic"
    return {"type": kind, "to_world": [[float(v) for v in row] for row in to_world],
            "frame": frame, "clip_start": clip_start, "clip_end": max(clip_end, clip_start + 1e-6)}


def ndc_rect(points_ndc) -> tuple[float, float, float, float]:
    xs = [p[0] for p in points_ndc]
    ys = [p[1] for p in points_ndc]
    return min(xs), min(ys), max(xs), max(ys)


def project(window_matrix, points_view) -> list[tuple[float, float]]:
    """View-space points → NDC (x, y)."""
    m = np.array(window_matrix, dtype=np.float64).reshape(4, 4)
    out = []
    for p in points_view:
        h = m @ np.array([p[0], p[1], p[2], 1.0])
        out.append((float(h[0] / h[3]), float(h[1] / h[3])))
    return out


def region_border(ndc_frame: tuple[float, float, float, float] | None, border, width: int, height: int):
    """A render border as region pixels (x0, y0, x1, y1; y from the bottom), or None.

    ``border`` = (min_x, min_y, max_x, max_y) as fractions of the camera frame (camera view:
    ``ndc_frame`` is the frame's NDC rectangle) or of the region (``ndc_frame`` None)."""
    if border is None:
        return None
    bx0, by0, bx1, by1 = border
    if ndc_frame is None:
        fx0, fy0, fx1, fy1 = 0.0, 0.0, float(width), float(height)
    else:
        fx0 = (ndc_frame[0] + 1.0) * 0.5 * width
        fx1 = (ndc_frame[2] + 1.0) * 0.5 * width
        fy0 = (ndc_frame[1] + 1.0) * 0.5 * height
        fy1 = (ndc_frame[3] + 1.0) * 0.5 * height
    return (fx0 + bx0 * (fx1 - fx0), fy0 + by0 * (fy1 - fy0),
            fx0 + bx1 * (fx1 - fx0), fy0 + by1 * (fy1 - fy0))


def film_crop(rect, width: int, height: int, pixel_size: int = 1):
    """Region pixels (x0, y0, x1, y1 from the bottom) → the film's ``crop`` (rows from the top)
    of a film of ``ceil(width / pixel_size)`` × ``ceil(height / pixel_size)`` pixels; None when
    the rectangle covers the whole film, (0, 0, 1, 1)-sized when it misses it entirely."""
    fw, fh = film_size(width, height, pixel_size)
    if rect is None:
        return None
    x0, y0, x1, y1 = (v / pixel_size for v in rect)
    cx0 = min(max(int(math.floor(x0)), 0), fw - 1)
    cx1 = min(max(int(math.ceil(x1)), cx0 + 1), fw)
    top0 = fh - y1
    top1 = fh - y0
    cy0 = min(max(int(math.floor(top0)), 0), fh - 1)
    cy1 = min(max(int(math.ceil(top1)), cy0 + 1), fh)
    if (cx0, cy0, cx1, cy1) == (0, 0, fw, fh):
        return None
    return [cx0, cy0, cx1, cy1]


def film_size(width: int, height: int, pixel_size: int = 1) -> tuple[int, int]:
    ps = max(1, int(pixel_size))
    return max(1, math.ceil(width / ps)), max(1, math.ceil(height / ps))
