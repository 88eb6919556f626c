"""Bake Procedural Textures (ops/bake.py): baked images, the export's use of them, and a render
of a procedural checker compared with Cycles."""
from __future__ import annotations

import json
import math
from pathlib import Path

import bpy
import numpy as np

from . import build
from .parity_cases import _render_both


def _checker_material(name="Checkered", scale=4.0):
    """A Diffuse BSDF whose Color is a Checker Texture (0.8 / 0.1 grey, Generated coordinates),
    roughness unchanged; a Bump node over a Wave Texture on its Normal."""
    mat = build.diffuse_material(name, (0.5, 0.5, 0.5))
    tree = mat.node_tree
    checker = tree.nodes.new("ShaderNodeTexChecker")
    checker.name = "Checker"
    checker.inputs["Scale"].default_value = scale
    checker.inputs["Color1"].default_value = (0.8, 0.8, 0.8, 1.0)
    checker.inputs["Color2"].default_value = (0.1, 0.1, 0.1, 1.0)
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse")
    tree.links.new(checker.outputs["Color"], bsdf.inputs["Color"])
    return mat, checker


def _export(tmp, name):
    from lamina.addon.export import export_scene
    result = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / name)
    return json.loads(result.path.read_text()), result


def bake_and_export(tmp):
    """Before baking the checker is named; after, the material's colour is the baked image, whose
    texels are the checker's two colours; changing the checker makes the bake stale (named)."""
    build.scene()
    build.camera()
    mat, checker = _checker_material()
    plane = build.plane("Floor", size=2.0, material=mat)
    doc, before = _export(tmp, "before")
    out = {"before": before.warning_text(), "before_color": doc["materials"]["Checkered"]["color"]}
    r = bpy.ops.lamina.bake_procedurals(material="Checkered", resolution=64)
    out["operator"] = sorted(r)
    image = bpy.data.images.get("Lamina bake: Checkered / Diffuse BSDF / Color")
    out["image"] = image is not None
    if image is not None:
        px = np.empty(64 * 64 * 4, np.float32)
        image.pixels.foreach_get(px)
        px = px.reshape(64, 64, 4)
        out["texel_values"] = sorted({round(float(v), 3) for v in px[..., 0].ravel()})
        out["packed"] = image.packed_file is not None
    out["nodes_after"] = sorted(n.bl_idname for n in mat.node_tree.nodes)
    out["objects_after"] = sorted(o.name for o in bpy.data.objects)
    doc, after = _export(tmp, "after")
    out["after"] = after.warning_text()
    out["after_color"] = doc["materials"]["Checkered"]["color"]
    checker.inputs["Scale"].default_value = 5.0
    doc, stale = _export(tmp, "stale")
    out["stale"] = stale.warning_text()
    out["stale_color"] = doc["materials"]["Checkered"]["color"]
    del plane
    return out


def checker_parity(tmp, spp=64, bounces=2):
    """A plane with a procedural checker (baked at 512²) under a sun, Lamina vs Cycles."""
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = 64, 64
    build.camera(location=(0.0, 0.0, 6.0), target=(0.0, 0.0, 0.0), lens=50)
    build.world_colour((0.02, 0.02, 0.02), 1.0)
    build.light("Sun", "SUN", location=(0, 0, 5), rotation=(0.0, math.radians(30.0), 0.0), energy=3.0,
                angle=0.0)
    mat, _ = _checker_material(scale=3.0)
    build.plane("Floor", size=2.0, material=mat)
    out = {"operator": sorted(bpy.ops.lamina.bake_procedurals(resolution=512))}
    out.update(_render_both(sc, tmp, "checker", spp, bounces))
    return out


def bake_awkward(tmp):
    """A two-material object (the checker on the left half's faces, plain grey on the right
    half's, one UV map over both), and a material used only by an object without UVs."""
    build.scene()
    build.camera()
    checkered, _ = _checker_material("Left")
    plain = build.diffuse_material("Right", (0.5, 0.5, 0.5))
    # Two quads side by side; UVs from x, y over both: the left quad fills u < 0.5.
    verts = [(-1, -1, 0), (0, -1, 0), (0, 1, 0), (-1, 1, 0), (1, -1, 0), (1, 1, 0)]
    obj = build.mesh_object("Split", verts, [(0, 1, 2, 3), (1, 4, 5, 2)])
    obj.data.materials.append(checkered)
    obj.data.materials.append(plain)
    obj.data.polygons[1].material_index = 1
    no_uv_mat, _ = _checker_material("NoUV")
    build.mesh_object("Bare", [(0, 0, 1), (1, 0, 1), (1, 1, 1)], [(0, 1, 2)], material=no_uv_mat, uv=False)
    out = {}
    bpy.ops.lamina.bake_procedurals(material="", resolution=64)
    image = bpy.data.images.get("Lamina bake: Left / Diffuse BSDF / Color")
    out["image"] = image is not None
    if image is not None:
        px = np.empty(64 * 64 * 4, np.float32)
        image.pixels.foreach_get(px)
        px = px.reshape(64, 64, 4)[..., 0]
        out["left_values"] = sorted({round(float(v), 3) for v in px[8:56, 4:28].ravel()})
        out["right_values"] = sorted({round(float(v), 3) for v in px[8:56, 40:60].ravel()})
    out["no_uv_baked"] = bpy.data.images.get("Lamina bake: NoUV / Diffuse BSDF / Color") is not None
    out["objects"] = sorted(o.name for o in bpy.data.objects)
    out["meshes"] = len(bpy.data.meshes)
    return out


def export_operator_bakes(tmp):
    """File > Export bakes what is not baked yet (and only that), at its resolution; without the
    option a changed checker is exported as its socket value and named as stale."""
    from lamina.addon.ops.bake import bake_materials, scene_materials
    build.scene()
    build.camera()
    mat, checker = _checker_material()
    build.plane("Floor", size=2.0, material=mat)
    path = Path(tmp) / "exported.json"
    out = {"first": sorted(bpy.ops.lamina.export_scene(filepath=str(path), bake_procedurals=True,
                                                       bake_resolution=32))}
    doc = json.loads(path.read_text())
    out["color"] = doc["materials"]["Checkered"]["color"]
    image = bpy.data.images.get("Lamina bake: Checkered / Diffuse BSDF / Color")
    out["size"] = list(image.size) if image is not None else None
    out["again"] = bake_materials(bpy.context, scene_materials(bpy.context.scene), 32, only_missing=True)[0]
    checker.inputs["Scale"].default_value = 5.0
    out["off"] = sorted(bpy.ops.lamina.export_scene(filepath=str(path), bake_procedurals=False))
    out["off_color"] = json.loads(path.read_text())["materials"]["Checkered"]["color"]
    from lamina.addon.export import export_scene
    out["off_warning"] = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / "check").warning_text()
    out["stale_baked"] = bake_materials(bpy.context, scene_materials(bpy.context.scene), 32, only_missing=True)[0]
    return out
