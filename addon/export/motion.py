"""Motion blur: objects' and the camera's transforms over the shutter.

With *Render Properties > Motion Blur* on, the scene is evaluated at ``STEPS`` equally spaced
times over the shutter (Blender's Shutter, in frames, placed by Cycles' Position: start, centre or
end on the frame) and each object whose transform changes gets ``"motion"``: its ``to_world`` at
those times (the backend interpolates linearly between them and samples each ray's time over the
shutter). Deforming meshes (armatures, shape keys, animated modifiers), moving lights and the
motion of instanced objects are not blurred: named in the warning.
"""
from __future__ import annotations

import math

from ..util import matrix_rows, without_scale

STEPS = 5            # transform samples over the shutter (a turning object's path: 4 segments)


def shutter_times(scene) -> list[float] | None:
    """Frame times of the transform samples, or None without motion blur."""
    render = scene.render
    if not getattr(render, "use_motion_blur", False):
        return None
    shutter = max(float(render.motion_blur_shutter), 0.0)
    if shutter == 0.0:
        return None
    frame = scene.frame_current + float(getattr(scene, "frame_current_final", scene.frame_current)
                                        - scene.frame_current)
    position = getattr(getattr(scene, "cycles", None), "motion_blur_position", "CENTER")
    start = {"START": frame, "END": frame - shutter}.get(position, frame - shutter / 2)
    return [start + shutter * k / (STEPS - 1) for k in range(STEPS)]


def sample(depsgraph, frame_set, times: list[float]) -> dict:
    """{object name: [4 × 4 matrix at each time]} of the depsgraph's objects (not instances),
    evaluated at ``times`` by ``frame_set(frame, subframe)``; the frame is restored after."""
    scene = depsgraph.scene
    frame, subframe = scene.frame_current, float(getattr(scene, "frame_subframe", 0.0))
    out: dict = {}
    try:
        for t in times:
            f = math.floor(t)
            frame_set(int(f), t - f)
            for obj in depsgraph.objects:
                out.setdefault(obj.name, []).append(obj.matrix_world.copy())
    finally:
        frame_set(frame, subframe)
    return out


def motion_rows(steps: list | None, rigid: bool = False) -> list | None:
    """The ``"motion"`` entry of sampled matrices (camera: ``rigid``, its scale removed as
    Cycles does), or None when they do not change over the shutter."""
    if not steps:
        return None
    rows = [matrix_rows(without_scale(m) if rigid else m) for m in steps]
    first = rows[0]
    if all(abs(a - b) <= 1e-9 for r in rows[1:] for ra, rb in zip(r, first) for a, b in zip(ra, rb)):
        return None
    return rows


def deformation_note(obj) -> str | None:
    """Why an object's mesh may change shape over the shutter (not blurred), or None."""
    if any(m.type in ("ARMATURE", "CLOTH", "SOFT_BODY", "OCEAN", "WAVE", "MESH_CACHE", "NODES")
           for m in getattr(obj, "modifiers", ())):
        return f"object '{obj.name}': deforming modifiers are not motion-blurred (its shape at the frame is used)"
    keys = getattr(getattr(obj, "data", None), "shape_keys", None)
    if keys is not None and keys.animation_data is not None:
        return f"object '{obj.name}': animated shape keys are not motion-blurred (its shape at the frame is used)"
    return None
