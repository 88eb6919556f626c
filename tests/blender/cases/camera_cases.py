"""Camera parity: Blender's own projection matrix vs the exported camera (run inside Blender)."""
from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Vector

from . import build


def projections(tmp, configs):
    """For each config, project random points with Blender's projection matrix
    (``Object.calc_matrix_camera`` @ view matrix, computed in C, no view_frame involved) and
    return them with the exported camera JSON."""
    from lamina.addon.export.camera import camera_json
    out = []
    rng = np.random.default_rng(7)
    for cfg in configs:
        bpy.ops.wm.read_homefile(use_empty=True)
        sc = build.scene()
        sc.render.resolution_x, sc.render.resolution_y = cfg["res"]
        sc.render.pixel_aspect_x, sc.render.pixel_aspect_y = cfg.get("pixel_aspect", (1.0, 1.0))
        cam = build.camera(location=(1.0, -5.0, 2.0), target=(0.2, 0.0, 0.6))
        cam.rotation_euler.y += 0.2      # a roll, so the image axes are not world-aligned
        data = cam.data
        data.type = cfg["type"]
        data.sensor_fit = cfg.get("fit", "AUTO")
        data.sensor_width, data.sensor_height = 36.0, 24.0
        data.shift_x, data.shift_y = cfg.get("shift", (0.0, 0.0))
        data.ortho_scale = 4.0
        bpy.context.view_layer.update()
        depsgraph = bpy.context.evaluated_depsgraph_get()
        w, h = sc.render.resolution_x, sc.render.resolution_y
        proj = cam.calc_matrix_camera(depsgraph, x=w, y=h, scale_x=sc.render.pixel_aspect_x,
                                      scale_y=sc.render.pixel_aspect_y)
        view = cam.matrix_world.normalized().inverted()
        # Points inside the view volume: random NDC and depth, mapped back through the inverse.
        inv = (proj @ view).inverted()
        points, pixels = [], []
        for _ in range(40):
            ndc = Vector((rng.uniform(-1.2, 1.2), rng.uniform(-1.2, 1.2), rng.uniform(-0.9, 0.99), 1.0))
            p = inv @ ndc
            p = p.xyz / p.w
            q = proj @ view @ p.to_4d()
            x_ndc, y_ndc = q.x / q.w, q.y / q.w
            points.append(list(p))
            # Blender pixels: x to the right from the left edge, y down from the top edge.
            pixels.append([(x_ndc + 1) * 0.5 * w, (1 - y_ndc) * 0.5 * h])
        out.append({"config": cfg, "camera": camera_json(cam, sc), "points": points, "pixels": pixels,
                    "size": [w, h]})
    return out
