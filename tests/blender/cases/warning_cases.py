"""Warnings, errors, IES peak, progress and stack cases (run by tests/blender/test_warnings.py)."""
from __future__ import annotations

import json
import math
from pathlib import Path

import bpy
import numpy as np

from . import build
from .ui_cases import Recorder, _calls

IES = Path(__file__).resolve().parents[2] / "data" / "ies" / "erco_narrow10_lm95.ies"


def _emissive(name):
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    emit = tree.nodes.new("ShaderNodeEmission")
    tree.links.new(emit.outputs[0], tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    return mat


def _feature_scene():
    """A scene using every feature the one warning must name."""
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = 16, 12
    build.camera()
    floor = build.plane("Floor", material=build.diffuse_material("Grey"))
    sc.render.use_motion_blur = True
    floor.modifiers.new("Rig", "ARMATURE")      # a deforming modifier: its motion is not blurred
    sc.render.use_multiview = True
    vl = bpy.context.view_layer
    for prop in ("use_pass_z", "use_pass_mist", "use_pass_normal", "use_pass_position", "use_pass_uv",
                 "use_pass_object_index", "use_pass_material_index", "use_pass_vector",
                 "use_pass_ambient_occlusion"):
        setattr(vl, prop, True)
    vl.lightgroups.add(name="Key")
    blocker = build.plane("Blocker", size=1, z=2.0)
    blocker.visible_shadow = False
    blocker.visible_diffuse = False
    blocker.visible_glossy = False
    blocker.visible_transmission = False
    lamp = build.light("Lamp", "POINT", (0, -1, 3), energy=200.0)
    receivers = bpy.data.collections.new("Receivers")
    receivers.objects.link(floor)
    lamp.light_linking.receiver_collection = receivers
    blockers = bpy.data.collections.new("Blockers")
    blockers.objects.link(blocker)
    lamp.light_linking.blocker_collection = blockers
    lamp.lightgroup = "Key"
    lamp.visible_shadow = False           # a light object's shadow switch is not rendered
    # An emissive object's light linking is rendered, its shadow linking is not.
    glow = build.plane("Glow", size=0.5, z=2.5, material=_emissive("Glowing"))
    glow.light_linking.receiver_collection = receivers
    glow.light_linking.blocker_collection = blockers
    # Shader features the integrator does not render (or no longer names): Mix/Add Shader, a
    # procedural normal map, a Bump node over a procedural height, a procedural texture, a
    # Volume output.
    mix = bpy.data.materials.new("Mixed")
    tree = mix.node_tree
    out = tree.nodes["Material Output"]
    mixer = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(mixer.outputs[0], out.inputs["Surface"])
    add = bpy.data.materials.new("Added")
    add_node = add.node_tree.nodes.new("ShaderNodeAddShader")
    add.node_tree.links.new(add_node.outputs[0], add.node_tree.nodes["Material Output"].inputs["Surface"])
    bumpy = bpy.data.materials.new("Bumpy")
    bsdf = bumpy.node_tree.nodes["Principled BSDF"]
    normal_map = bumpy.node_tree.nodes.new("ShaderNodeNormalMap")
    bumpy.node_tree.links.new(normal_map.outputs[0], bsdf.inputs["Normal"])
    noise = bumpy.node_tree.nodes.new("ShaderNodeTexNoise")
    bumpy.node_tree.links.new(noise.outputs["Color"], bsdf.inputs["Base Color"])
    # a procedural normal map (only image textures are translated)
    bumpy.node_tree.links.new(noise.outputs["Color"], normal_map.inputs["Color"])
    foggy = bpy.data.materials.new("Foggy")
    vol = foggy.node_tree.nodes.new("ShaderNodeVolumePrincipled")
    foggy.node_tree.links.new(vol.outputs[0], foggy.node_tree.nodes["Material Output"].inputs["Volume"])
    bump_mat = bpy.data.materials.new("Bumped")
    bump = bump_mat.node_tree.nodes.new("ShaderNodeBump")
    bump_mat.node_tree.links.new(bump.outputs[0], bump_mat.node_tree.nodes["Principled BSDF"].inputs["Normal"])
    # a procedural height (only image textures are translated)
    wave = bump_mat.node_tree.nodes.new("ShaderNodeTexWave")
    bump_mat.node_tree.links.new(wave.outputs["Fac"], bump.inputs["Height"])
    # EEVEE's Shader to RGB (Cycles renders it black: baking cannot help).
    toon = bpy.data.materials.new("Toon")
    to_rgb = toon.node_tree.nodes.new("ShaderNodeShaderToRGB")
    toon.node_tree.links.new(to_rgb.outputs["Color"], toon.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    for i, mat in enumerate((mix, add, bumpy, foggy, bump_mat, toon)):
        build.uv_sphere(f"Ball{i}", radius=0.3, segments=8, rings=4, material=mat, location=(i - 2, 0, 0.5))
    # A world volume (mist): not rendered.
    world = build.world_colour((0.1, 0.1, 0.1))
    tree = world.node_tree
    output = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld")
    scatter = tree.nodes.new("ShaderNodeVolumeScatter")
    tree.links.new(scatter.outputs[0], output.inputs["Volume"])
    return sc


def export_warning(tmp):
    from lamina.addon.export import export_scene
    _feature_scene()
    result = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / "features",
                          frame_set=lambda f, sub: bpy.context.scene.frame_set(f, subframe=sub))
    return {"warning": result.warning_text(limit=100), "notes": result.notes}


def render_warning(tmp):
    """Render with the fake backend: the one warning (export notes + the renderer's), on stderr."""
    from .engine_cases import _fake_backend, _render_to, _reset_backend
    sc = _feature_scene()
    sc.render.use_multiview = False          # (the fake writes one view)
    _fake_backend(tmp, "pixels")
    error, _ = _render_to(sc, Path(tmp) / "warn.exr")
    _reset_backend()
    return {"message": error, "done": True}


def named_error(tmp):
    """A broken image texture: the renderer's error names the material and node, once."""
    from .engine_cases import _render_to, _simple_scene
    sc = _simple_scene()
    bad = Path(tmp) / "broken.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n this is not a png")
    mat = bpy.data.materials["Grey"]
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.name = "Wood Grain"
    tex.image = bpy.data.images.load(str(bad), check_existing=False)
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse")
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    sc.lamina.samples = 1
    sc.lamina.fail_on_missing_textures = True      # (off: the texture renders magenta)
    error, _ = _render_to(sc, Path(tmp) / "err.exr")
    return {"message": error, "done": True}


def missing_texture(tmp):
    """An image texture whose file is gone: by default the render finishes, the texture magenta
    (as Cycles) and one warning naming the material, the node and the file."""
    import OpenImageIO as oiio
    from .engine_cases import _render_to, _simple_scene
    sc = _simple_scene()
    gone = Path(tmp) / "gone_wood.png"
    out = oiio.ImageOutput.create(str(gone))
    out.open(str(gone), oiio.ImageSpec(2, 2, 3, oiio.UINT8))
    out.write_image(np.full((2, 2, 3), 128, np.uint8))
    out.close()
    mat = bpy.data.materials["Grey"]
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.name = "Wood Grain"
    tex.image = bpy.data.images.load(str(gone), check_existing=False)
    gone.unlink()                                  # moved away after the .blend was made
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse")
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    sc.lamina.samples = 4
    error, _ = _render_to(sc, Path(tmp) / "magenta.exr")
    inp = oiio.ImageInput.open(str(Path(tmp) / "magenta.exr"))       # scene-linear, as rendered
    spec = inp.spec()
    names = list(spec.channelnames)
    data = np.asarray(inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)).reshape(spec.height, spec.width, -1)
    inp.close()
    pixels = data[:, :, [next(i for i, n in enumerate(names) if n.endswith(f"Combined.{c}")) for c in "RGB"]]
    h, w = pixels.shape[:2]
    # The floor fills rows 8-9 of 12 (top row first) between the horizon and the camera.
    centre = pixels[8:10, w // 4:3 * w // 4].reshape(-1, 3).mean(axis=0)
    return {"message": error, "centre": [float(c) for c in centre], "file": str(gone)}


def opaque_stack(tmp):
    """A layer added under the last (conductor) one: the export leaves it out, with a note."""
    from lamina.addon.export import export_scene
    from lamina.addon.ops.stack import add_layer
    from lamina.addon.stack_check import check_material
    from lamina.addon.export.images import ImageExporter
    from lamina.addon.export.stack import stack_json
    build.scene()
    build.camera()
    mat = bpy.data.materials.new("Coated Copper")
    s = mat.lamina
    coat = add_layer(s, "DIELECTRIC", 0)
    coat.name = "Coat"
    base = add_layer(s, "CONDUCTOR", 1)
    base.name = "Copper"
    under = add_layer(s, "DIFFUSE", 2)
    under.name = "Under"
    s.use_stack = True
    build.plane(material=mat)
    build.light("Lamp", "POINT", (0, -1, 3), energy=200.0)
    result = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / "opaque")
    doc = json.loads(result.path.read_text())
    notes: list[str] = []
    panel = check_material(stack_json(mat, ImageExporter(None, False, notes)))
    return {"material": doc["materials"]["Coated Copper"], "notes": result.notes, "path": str(result.path),
            "panel": panel + [["WARNING", n] for n in notes]}


def ies_panel(tmp):
    from lamina.addon.ui.light import draw_ies
    build.scene()
    lamp = build.light("Spot", "SPOT", (0, 0, 3), energy=1000.0, spot_size=math.radians(60))
    lamp.data.lamina.ies_mode = "FILE"
    lamp.data.lamina.ies_file = str(IES)
    log = Recorder()
    draw_ies(log, lamp.data)
    labels = [c for c in _calls(log._log) if c[0] == "label"]
    lamp.data.exposure = 1.0
    log2 = Recorder()
    draw_ies(log2, lamp.data)
    # The IES Texture node path (a Cycles light node tree), with its Strength.
    node_lamp = build.light("NodeSpot", "SPOT", (0, 0, 3), energy=10.0)
    node_lamp.data.use_nodes = True
    tree = node_lamp.data.node_tree
    ies = tree.nodes.new("ShaderNodeTexIES")
    ies.mode = "EXTERNAL"
    ies.filepath = str(IES)
    ies.inputs["Strength"].default_value = 2.0
    log3 = Recorder()
    draw_ies(log3, node_lamp.data)
    return {"labels": labels, "labels_exposure": [c for c in _calls(log2._log) if c[0] == "label"],
            "labels_node": [c for c in _calls(log3._log) if c[0] == "label"]}


def progress_texts(tmp):
    from lamina.addon.engine.engine import progress_text
    events = [{"event": "progress", "done": 0, "samples": 18.5, "total": 64, "elapsed": 1.0, "eta": 2.5},
              {"event": "progress", "done": 37, "samples": 37, "total": 64, "elapsed": 2.0, "eta": 1.46},
              {"event": "progress", "done": 64, "samples": 64, "total": 64, "elapsed": 3.4, "eta": 0.0},
              {"event": "progress", "done": 4, "total": 16, "elapsed": 0.1, "eta": 0.3}]       # an old backend
    return [progress_text(e) for e in events]


def animation_warnings(tmp):
    """A three-frame animation of a scene whose every frame has the same warning."""
    from .engine_cases import render_animation
    sc = _feature_scene()
    sc.render.use_multiview = False
    sc.frame_start, sc.frame_end = 1, 3
    error, files = render_animation(sc, tmp)
    return {"error": error, "frames": len(files)}
