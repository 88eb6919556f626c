"""The stack's approximation for other engines (addon/ops/viewport_colour.py) on a fresh material."""
from __future__ import annotations

import importlib

import bpy

from . import build


def approximation(tmp):
    package = __import__("os").environ["LAMINA_TEST_PACKAGE"]
    vc = importlib.import_module(f"{package}.addon.ops.viewport_colour")
    presets = importlib.import_module(f"{package}.addon.ops.presets")
    library = importlib.import_module(f"{package}.addon.presets.library")
    build.scene()
    mat = bpy.data.materials.new("Paint")
    tree = mat.node_tree
    users_output = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    presets.apply_preset(mat, library.find("car-paint-red"))
    before = tree.get_output_node("ALL").name            # background mode: nothing measured yet
    ok = vc.update_now(mat)
    active = tree.get_output_node("ALL").name
    bsdf = tree.nodes[vc.NODE]
    colour = list(bsdf.inputs["Base Color"].default_value)[:3]
    again = vc.update_now(mat)                            # unchanged stack: nothing new, same values
    mat.lamina.use_stack = False
    vc.release(mat)
    after_off = tree.get_output_node("ALL").name
    return {"before": before, "ok": ok, "again": again, "active": active, "colour": colour,
            "metallic": bsdf.inputs["Metallic"].default_value, "users_output": users_output.name,
            "after_off": after_off, "nodes": len(tree.nodes)}
