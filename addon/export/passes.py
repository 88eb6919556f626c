"""The view layer's data passes → the scene file's ``passes`` section, and the render-result
passes the engine registers for them. (Blender names and switches only: the passes themselves,
Cycles' conventions included, are the backend's, backend/passes.py.)"""
from __future__ import annotations

# View-layer switch → (scene-file pass, Blender pass name, channel ids, kind), in Cycles' order.
RENDERED = (
    ("use_pass_z", "depth", "Depth", "Z", "VALUE"),
    ("use_pass_mist", "mist", "Mist", "Z", "VALUE"),
    ("use_pass_position", "position", "Position", "XYZ", "VECTOR"),
    ("use_pass_normal", "normal", "Normal", "XYZ", "VECTOR"),
    ("use_pass_uv", "uv", "UV", "UVA", "VECTOR"),
    ("use_pass_object_index", "object_index", "Object Index", "X", "VALUE"),
    ("use_pass_material_index", "material_index", "Material Index", "X", "VALUE"),
)

# Blender's world mist falloff → the scene file's.
FALLOFF = {"QUADRATIC": "quadratic", "LINEAR": "linear", "INVERSE_QUADRATIC": "inverse_quadratic"}


def requested(view_layer) -> list[tuple[str, str, str, str]]:
    """(scene-file name, Blender pass name, channel ids, kind) of the passes switched on."""
    if view_layer is None:
        return []
    return [(name, label, chans, kind) for prop, name, label, chans, kind in RENDERED
            if getattr(view_layer, prop, False)]


def passes_json(view_layer, world) -> dict | None:
    """The ``passes`` section (None when no data pass is on): mist takes the world's settings."""
    on = requested(view_layer)
    if not on:
        return None
    out = {name: {} for name, _, _, _ in on}
    if "mist" in out:
        mist = getattr(world, "mist_settings", None) if world is not None else None
        if mist is not None:
            out["mist"] = {"start": max(float(mist.start), 0.0), "depth": max(float(mist.depth), 0.0),
                           "falloff": FALLOFF.get(mist.falloff, "quadratic")}
    return out
