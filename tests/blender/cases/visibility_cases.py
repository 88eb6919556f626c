"""Ray visibility, light linking and shadow linking rendered by Cycles and by Lamina (run inside
Blender by tests/blender/test_visibility_parity.py).

Every scene is seen from straight above by an orthographic camera covering ``HALF`` metres
either side of the origin, so a world rectangle maps to a pixel box; each scene returns the
boxes (``regions``: name → [x0, y0, x1, y1] in world metres) whose means the test compares.
Both renderers run with every limit matched (parity_cases._match_cycles).
"""
from __future__ import annotations

import json
from pathlib import Path

import bpy

from . import build
from .parity_cases import _match_cycles

HALF = 4.0
PIXELS = 64


def _view(sc):
    sc.render.resolution_x = sc.render.resolution_y = PIXELS
    cam = bpy.data.cameras.new("cam")
    cam.type = "ORTHO"
    cam.ortho_scale = 2 * HALF
    co = build.link(bpy.data.objects.new("cam", cam))
    co.location = (0.0, 0.0, 10.0)
    sc.camera = co


def _square(name, x, y, z, size, material, down=False):
    obj = build.plane(name, size=size, material=material)
    obj.location = (x, y, z)
    if down:
        obj.rotation_euler = (3.14159265, 0.0, 0.0)
    return obj


def _node_material(name, kind, **inputs):
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    node = tree.nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    tree.links.new(node.outputs[0], tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    return mat


def _emitter(name, strength):
    return _node_material(name, "ShaderNodeEmission", Strength=strength, Color=(1.0, 0.95, 0.9, 1.0))


def _collection(name, objects, state):
    col = bpy.data.collections.new(name)
    for obj in objects:
        col.objects.link(obj)
    for item in col.collection_objects:
        item.light_linking.link_state = state
    return col


def _box(x, y, size, margin=0.15):
    h = size / 2 - margin
    return [x - h, y - h, x + h, y + h]


def light_linking():
    """A point light that excludes square A (B is lit), an emissive panel facing down that
    lights only square C (the floor around C gets none of its light)."""
    sc = build.scene()
    _view(sc)
    grey = build.diffuse_material("Grey", (0.7, 0.7, 0.7))
    build.plane("Floor", size=2 * HALF, material=grey)
    a = _square("A", -2.0, 2.0, 0.05, 1.5, grey)
    _square("B", 2.0, 2.0, 0.05, 1.5, grey)
    c = _square("C", 0.0, -2.0, 0.05, 1.0, grey)
    lamp = build.light("Lamp", "POINT", (0.0, 2.0, 2.5), energy=200.0)
    lamp.light_linking.receiver_collection = _collection("NotA", [a], "EXCLUDE")
    panel = _square("Panel", 0.0, -2.0, 1.0, 1.6, _emitter("Glow", 4.0), down=True)
    panel.visible_camera = False
    panel.light_linking.receiver_collection = _collection("OnlyC", [c], "INCLUDE")
    build.world_colour((0.0, 0.0, 0.0), 0.0)
    return {"A": _box(-2, 2, 1.5), "B": _box(2, 2, 1.5), "C": _box(0, -2, 1.0),
            "floor by C": [0.75, -2.6, 1.3, -1.4]}


def shadow_linking():
    """A point light whose shadows only P casts (Q casts none), an area light whose shadows
    every object but R casts, and S, invisible to shadow rays, which casts none for either."""
    sc = build.scene()
    _view(sc)
    grey = build.diffuse_material("Grey", (0.7, 0.7, 0.7))
    build.plane("Floor", size=2 * HALF, material=grey)
    p = _square("P", -2.0, 2.0, 1.0, 1.0, grey)
    q = _square("Q", 2.0, 2.0, 1.0, 1.0, grey)
    r = _square("R", -2.0, -2.0, 1.0, 1.0, grey)
    s = _square("S", 2.0, -2.0, 1.0, 1.0, grey)
    s.visible_shadow = False
    for obj in (p, q, r, s):
        obj.visible_camera = False            # the camera looks at the floor below them
    point = build.light("Spot", "POINT", (0.0, 2.0, 3.0), energy=300.0)
    point.light_linking.blocker_collection = _collection("OnlyP", [p], "INCLUDE")
    area = build.light("Panel", "AREA", (0.0, -2.0, 3.0), energy=400.0, size=2.0)
    area.light_linking.blocker_collection = _collection("NotR", [r], "EXCLUDE")
    build.world_colour((0.0, 0.0, 0.0), 0.0)
    # The shadows of the squares 1 m above the floor, lights 3 m up: 1.5× the square, centred
    # 1.5× as far from the point under the light.
    return {"under P": _box(-3.0, 2.0, 1.5, 0.3), "under Q": _box(3.0, 2.0, 1.5, 0.3),
            "under R": _box(-3.0, -2.0, 1.5, 0.3), "under S": _box(3.0, -2.0, 1.5, 0.3)}


def ray_types():
    """Emitters hidden from one ray type above a diffuse and a mirror patch each (a hidden
    emitter neither lights nor shows in that kind of bounce), and a red square under a glass
    cover that hides it from transmission rays (the camera sees the floor through the glass)."""
    sc = build.scene()
    _view(sc)
    grey = build.diffuse_material("Grey", (0.5, 0.5, 0.5))
    build.plane("Floor", size=2 * HALF, material=grey)
    # A smooth mirror (Glossy BSDF, roughness 0): it reflects its colour exactly in both
    # renderers, so the glossy patches compare the visibility alone, not two metal models.
    metal = _node_material("Metal", "ShaderNodeBsdfGlossy", Roughness=0.0, Color=(0.9, 0.9, 0.9, 1.0))
    matte = build.diffuse_material("Matte", (0.8, 0.8, 0.8))
    for i, (hide, y) in enumerate((("visible_diffuse", 2.0), ("visible_glossy", -0.5))):
        _square(f"Matte{i}", -2.5, y, 0.02, 1.4, matte)
        _square(f"Metal{i}", -0.8, y, 0.02, 1.4, metal)
        panel = _square(f"Panel{i}", -1.65, y, 0.8, 3.4, _emitter(f"Glow{i}", 3.0), down=True)
        panel.scale = (1.0, 0.6, 1.0)
        panel.visible_camera = False
        setattr(panel, hide, False)
    red = build.diffuse_material("Red", (0.8, 0.05, 0.05))
    hidden = _square("Hidden", 2.5, 2.0, 0.02, 1.4, red)
    hidden.visible_transmission = False
    _square("Shown", 2.5, -0.5, 0.02, 1.4, red)
    # IOR 1: the cover transmits everything straight on (no Fresnel reflection, no refraction
    # of a one-sided plane to tell apart), so what the camera sees through it is exact.
    glass = _node_material("Glass", "ShaderNodeBsdfGlass", Roughness=0.0, IOR=1.0)
    _square("Cover", 2.5, 0.75, 0.5, 2.0, glass).scale = (1.0, 2.4, 1.0)
    build.world_colour((0.2, 0.2, 0.2), 1.0)
    return {"matte, no diffuse": _box(-2.5, 2.0, 1.4), "metal, no diffuse": _box(-0.8, 2.0, 1.4),
            "matte, no glossy": _box(-2.5, -0.5, 1.4), "metal, no glossy": _box(-0.8, -0.5, 1.4),
            "glass over hidden": _box(2.5, 2.0, 1.4), "glass over shown": _box(2.5, -0.5, 1.4)}


def _pair(tmp, name, make, spp=256, bounces=4):
    """The scene ``make`` builds, rendered by Cycles and by Lamina."""
    from .engine_cases import _render_to
    regions = make()
    sc = bpy.context.scene
    _match_cycles(sc, spp, bounces)
    entry = {"regions": regions, "half": HALF}
    for engine in ("cycles", "lamina"):
        if engine == "lamina":
            sc.render.engine = "LAMINA"
            sc.lamina.samples = spp
            sc.lamina.max_bounces = bounces
            sc.lamina.rr_depth = 64
            sc.lamina.workers = 2
        path = Path(tmp) / f"{name}_{engine}.exr"
        entry[f"{engine}_error"], entry[f"{engine}_seconds"] = _render_to(sc, path, multilayer=False)
        entry[engine] = str(path)
    # What the add-on wrote for this scene.
    from lamina.addon.export import export_scene
    res = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / f"{name}_export")
    doc = json.loads(Path(res.path).read_text())
    entry["exported"] = {"objects": doc["objects"], "lights": doc["lights"], "notes": res.notes}
    return entry


def light_linking_pair(tmp):
    return _pair(tmp, "light_linking", light_linking)


def shadow_linking_pair(tmp):
    return _pair(tmp, "shadow_linking", shadow_linking)


def ray_types_pair(tmp):
    return _pair(tmp, "ray_types", ray_types)
