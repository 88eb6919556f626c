"""Material preview thumbnails through the LAMINA engine (run inside Blender)."""
from __future__ import annotations

import time

import bpy
import numpy as np

from . import build


def generate_preview(mat) -> None:
    """Ask Blender for a material's preview (a background job; pixels arrive later)."""
    try:
        with bpy.context.temp_override(id=mat):
            bpy.ops.ed.lib_id_generate_preview()
    except RuntimeError:            # bpy 5.3: the operator's poll needs a UI context; same job
        mat.asset_generate_preview()


def preview(tmp, timeout=240.0):       # (a first preview in a new checkout may compile kernels)
    sc = build.scene()
    mat = build.diffuse_material("Preview", (0.8, 0.2, 0.1))
    mat.preview_render_type = "SPHERE"
    t0 = time.perf_counter()
    generate_preview(mat)
    # The preview buffer exists as soon as the job starts; wait until pixels arrive.
    px = None
    while time.perf_counter() - t0 < timeout:
        w, h = mat.preview.image_size
        if w:
            px = np.array(mat.preview.image_pixels_float[:], dtype=np.float32).reshape(h, w, 4)
            if px[:, :, :3].max() > 0:
                break
        time.sleep(0.1)
    first = time.perf_counter() - t0
    # Then until the image stops changing (the final result replaced the progressive ones).
    last_change = first
    while px is not None and time.perf_counter() - t0 < timeout:
        time.sleep(0.5)
        now = np.array(mat.preview.image_pixels_float[:], dtype=np.float32).reshape(px.shape)
        if not np.array_equal(now, px):
            px, last_change = now, time.perf_counter() - t0
        elif time.perf_counter() - t0 - last_change > 2.0:
            break
    seconds = last_change
    w, h = mat.preview.image_size
    out = {"seconds": seconds, "first_pixels": first, "size": [w, h]}
    if px is not None:
        centre = px[h // 2 - 8:h // 2 + 8, w // 2 - 8:w // 2 + 8, :3].reshape(-1, 3)
        out.update(centre=centre.mean(axis=0).tolist(), finite=bool(np.isfinite(px).all()),
                   mean=float(px[:, :, :3].mean()))
    return out
