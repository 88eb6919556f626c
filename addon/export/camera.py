"""Camera and film: Blender's own image-plane corners (``Camera.view_frame``) carry sensor fit,
shift and aspect, so nothing of Blender's projection is re-derived here."""
from __future__ import annotations

from ..util import degrees, matrix_rows, without_scale


class CameraError(Exception):
    pass


def film_size(render) -> tuple[int, int]:
    s = render.resolution_percentage / 100.0
    return max(1, int(render.resolution_x * s)), max(1, int(render.resolution_y * s))


def border_rect(render, width: int, height: int):
    """Blender's border region as (x, y_from_bottom, w, h) pixels, or None (no border).

    Matches what ``RenderEngine.begin_result`` expects: the render result of a border render
    covers exactly this region (measured with bpy 5.0.1)."""
    if not render.use_border:
        return None
    x0 = round(render.border_min_x * width)
    x1 = round(render.border_max_x * width)
    y0 = round(render.border_min_y * height)
    y1 = round(render.border_max_y * height)
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1 - x0, y1 - y0


def film_json(scene, width: int, height: int) -> dict:
    render = scene.render
    settings = scene.lamina
    out = {"width": width, "height": height,
           "filter": {"type": settings.filter_type.lower().replace("_", "-"),
                      "width": round(float(settings.filter_width), 6)}}
    if settings.filter_type == "BOX":
        out["filter"] = {"type": "box", "width": 1.0}
    if render.film_transparent:
        out["transparent"] = True
    rect = border_rect(render, width, height)
    if rect is not None:
        x, y, w, h = rect
        out["crop"] = [x, height - (y + h), x + w, height - y]     # rows counted from the top
    return out


def camera_json(camera_object, scene) -> dict:
    cam = camera_object.data
    if cam.type == "PANO":
        raise CameraError(f"camera '{camera_object.name}': panoramic cameras are not supported")
    frame = [[float(c) for c in corner] for corner in cam.view_frame(scene=scene)]
    out = {"type": "orthographic" if cam.type == "ORTHO" else "perspective",
           # Cycles ignores the camera object's scale; so do we.
           "to_world": matrix_rows(without_scale(camera_object.matrix_world)),
           "frame": frame,
           "clip_start": float(cam.clip_start),
           "clip_end": float(cam.clip_end)}
    dof = cam.dof
    if dof.use_dof and cam.type == "PERSP" and dof.aperture_fstop > 0:
        distance = float(dof.focus_distance)
        if dof.focus_object is not None:
            # Distance along the view axis, as Blender measures it.
            inv = camera_object.matrix_world.normalized().inverted()
            target = dof.focus_object.matrix_world.translation
            if getattr(dof, "focus_subtarget", "") and dof.focus_object.type == "ARMATURE":
                bone = dof.focus_object.pose.bones.get(dof.focus_subtarget)
                if bone is not None:
                    target = dof.focus_object.matrix_world @ bone.head
            distance = max(-(inv @ target).z, 1e-6)
        # Thin lens: aperture radius = focal length / (2 · f-number), in metres (lens is in mm).
        radius = cam.lens * 1e-3 / (2.0 * dof.aperture_fstop)
        out["dof"] = {"focus_distance": max(distance, 1e-6), "aperture_radius": radius,
                      "blades": int(dof.aperture_blades) if dof.aperture_blades >= 3 else 0,
                      "rotation": degrees(dof.aperture_rotation),
                      "ratio": min(float(dof.aperture_ratio), 1000.0)}  # the format's range
    return out


def view_camera_object(scene, camera_object, view_name: str):
    """The camera of a view (Blender's rule for the *Multi-View* format): the camera whose name is
    the active camera's with its view suffix replaced by this view's suffix (``Cam_L`` →
    ``Cam_R``), if such an object exists; otherwise (and for *Stereo 3D*) the active camera."""
    render = scene.render
    if not render.use_multiview or render.views_format != "MULTIVIEW" or camera_object is None:
        return camera_object
    view = render.views.get(view_name)
    if view is None:
        return camera_object
    name = camera_object.name
    base = None
    longest = -1
    for other in render.views:           # the longest suffix that ends the camera's name
        suffix = other.camera_suffix
        if len(suffix) >= longest and len(suffix) <= len(name) and name.endswith(suffix):
            base, longest = name[:len(name) - len(suffix)], len(suffix)
    if base is None:
        return camera_object
    found = scene.objects.get(base + view.camera_suffix)
    return found if found is not None and found.type == "CAMERA" else camera_object


def eye_camera_json(camera_object, scene, matrix, shift_x: float) -> dict:
    """``camera_json`` of one view: ``matrix`` and ``shift_x`` are what Blender gives the view
    (``RenderEngine.camera_model_matrix`` / ``camera_shift_x``: the eye's position and, for
    off-axis stereo, its extra lens shift). The frame moves sideways by the shift difference in
    units of the sensor-fitted frame side (Blender's shift unit)."""
    out = camera_json(camera_object, scene)
    out["to_world"] = matrix_rows(without_scale(matrix))
    cam = camera_object.data
    delta = float(shift_x) - float(cam.shift_x)
    if delta != 0.0:
        tr, br, bl, tl = out["frame"]
        fit = cam.sensor_fit
        if fit == "AUTO":
            render = scene.render
            sx = render.resolution_x * render.pixel_aspect_x
            sy = render.resolution_y * render.pixel_aspect_y
            fit = "HORIZONTAL" if sx >= sy else "VERTICAL"
        side = (tr[0] - tl[0]) if fit == "HORIZONTAL" else (tl[1] - bl[1])
        out["frame"] = [[c[0] + delta * side, c[1], c[2]] for c in out["frame"]]
    return out
