"""What a scene uses that Lamina does not render: one note per thing, naming the data-block.

Every note is ``"<kind> '<name>': <what> (<what Lamina does instead>)"``, so the render's one
warning (``scene.warning_text``) groups them by object, material, light, view layer or scene.
Checked here: a light object's shadow ray visibility, shadow linking set on an
emissive object, light groups, shadow catchers, a light's shadow/contribution switches, and render
passes other than Combined, the denoising passes and the data passes of passes.py. (Ray
visibility of objects and lights and light linking of lights and emissive objects are rendered:
linking.py; stereo / multi-view renders every view from its own camera: engine.py. Shader nodes
are checked by nodes.py, geometry types by scene.py, textures by images.py.)
"""
from __future__ import annotations

# View-layer pass switches Lamina does not write: (property, label). Combined and the denoising
# passes (Denoising Albedo, Denoising Normal) are always written; Depth, Mist, Normal, Position,
# UV, Object Index and Material Index when switched on (passes.RENDERED).
PASSES = (
    ("use_pass_vector", "Vector"),
    ("use_pass_shadow", "Shadow"), ("use_pass_ambient_occlusion", "Ambient Occlusion"),
    ("use_pass_emit", "Emission"), ("use_pass_environment", "Environment"),
    ("use_pass_diffuse_direct", "Diffuse Direct"), ("use_pass_diffuse_indirect", "Diffuse Indirect"),
    ("use_pass_diffuse_color", "Diffuse Color"), ("use_pass_glossy_direct", "Glossy Direct"),
    ("use_pass_glossy_indirect", "Glossy Indirect"), ("use_pass_glossy_color", "Glossy Color"),
    ("use_pass_transmission_direct", "Transmission Direct"),
    ("use_pass_transmission_indirect", "Transmission Indirect"),
    ("use_pass_transmission_color", "Transmission Color"),
    ("use_pass_subsurface_direct", "Subsurface Direct"),
    ("use_pass_subsurface_indirect", "Subsurface Indirect"),
    ("use_pass_subsurface_color", "Subsurface Color"),
    ("use_pass_cryptomatte_object", "Cryptomatte Object"),
    ("use_pass_cryptomatte_material", "Cryptomatte Material"),
    ("use_pass_cryptomatte_asset", "Cryptomatte Asset"),
)

# Ray-visibility switches Lamina does not honour: none on objects (camera, diffuse, glossy,
# transmission and shadow rays are rendered); on a light object the shadow switch (its shadows
# are Blender's Cast Shadow, noted below). Volume scatter is left out: Lamina renders no volumes.
RAY_VISIBILITY = {"object": (), "light": (("visible_shadow", "shadow"),)}


def scene_notes(scene, view_layer) -> list[str]:
    """Scene- and view-layer-wide settings Lamina does not render."""
    notes = []
    if view_layer is not None:
        on = [label for prop, label in PASSES if getattr(view_layer, prop, False)]
        cycles = getattr(view_layer, "cycles", None)
        if cycles is not None:
            for prop, label in (("use_pass_shadow_catcher", "Shadow Catcher"),
                                ("use_pass_volume_direct", "Volume Direct"),
                                ("use_pass_volume_indirect", "Volume Indirect")):
                if getattr(cycles, prop, False):
                    on.append(label)
        if len(getattr(view_layer, "aovs", ())):
            on.append("shader AOVs")
        if on:
            notes.append(f"view layer '{view_layer.name}': {', '.join(on)} pass"
                         f"{'es' if len(on) > 1 else ''} (not rendered: left empty)")
        groups = [g.name for g in getattr(view_layer, "lightgroups", ())]
        if groups:
            notes.append(f"view layer '{view_layer.name}': light groups {', '.join(groups)} "
                         f"(not rendered: no light group passes)")
    return notes


def object_notes(obj, kind: str) -> list[str]:
    """Per-object settings Lamina ignores (``kind``: 'object' or 'light', for the message)."""
    notes = []
    original = obj.original if getattr(obj, "original", None) is not None else obj
    hidden = [label for prop, label in RAY_VISIBILITY.get(kind, ()) if not getattr(original, prop, True)]
    if hidden:
        notes.append(f"{kind} '{original.name}': ray visibility off for {', '.join(hidden)} rays "
                     f"(ignored: seen by every ray)")
    linking = getattr(original, "light_linking", None)
    if linking is not None and kind == "object" and getattr(linking, "blocker_collection", None) is not None:
        # Light linking of lights and emissive objects and shadow linking of lights are
        # rendered; an emissive object's blockers are not (its emission found by BSDF sampling
        # would need a dedicated ray past non-blockers, which Lamina traces only for lights).
        notes.append(f"{kind} '{original.name}': shadow linking to collection "
                     f"'{linking.blocker_collection.name}' (ignored: every object casts shadows)")
    if getattr(original, "lightgroup", ""):
        notes.append(f"{kind} '{original.name}': light group '{original.lightgroup}' (ignored)")
    if kind == "object" and getattr(original, "is_shadow_catcher", False):
        notes.append(f"{kind} '{original.name}': shadow catcher (rendered as an ordinary object)")
    return notes


def light_data_notes(obj) -> list[str]:
    """A light's own switches that Lamina ignores."""
    light = obj.data
    notes = []
    if not getattr(light, "use_shadow", True):
        notes.append(f"light '{obj.name}': Cast Shadow off (ignored: it casts shadows)")
    factors = [(name, getattr(light, prop, 1.0)) for prop, name in
               (("diffuse_factor", "Diffuse"), ("specular_factor", "Glossy"),
                ("transmission_factor", "Transmission"))]
    changed = [f"{name} {value:g}" for name, value in factors if abs(float(value) - 1.0) > 1e-6]
    if changed:
        notes.append(f"light '{obj.name}': contribution factors {', '.join(changed)} (ignored: 1)")
    if getattr(light, "use_custom_distance", False):
        notes.append(f"light '{obj.name}': custom distance (ignored: no cutoff)")
    return notes
