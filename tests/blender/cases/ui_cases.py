"""Properties, operators, panels and presets (run inside Blender by tests/blender/test_ui.py)."""
from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import bpy

from . import build


class Recorder:
    """A stand-in for UILayout: records every call (method, args, kwargs) into a shared log."""

    def __init__(self, log=None, path="layout"):
        object.__setattr__(self, "_log", [] if log is None else log)
        object.__setattr__(self, "_path", path)

    def __getattr__(self, name):
        def call(*args, **kwargs):
            self._log.append((name, args, kwargs))
            return Recorder(self._log, f"{self._path}.{name}")
        return call

    def __setattr__(self, name, value):
        self._log.append(("set:" + name, (value,), {}))


ALL_LOGS: list = []


def _icons_unknown() -> list[str]:
    """Icons used in any recorded draw call that Blender does not know (they fail in the UI)."""
    known = {i.identifier for i in bpy.types.UILayout.bl_rna.functions["prop"].parameters["icon"].enum_items}
    used = {kw["icon"] for log in ALL_LOGS for _, _, kw in log if "icon" in kw}
    return sorted(used - known)


def _calls(log):
    """JSON-friendly summary: (method, [property names / texts])."""
    ALL_LOGS.append(log)
    out = []
    for name, args, kwargs in log:
        if name == "prop" and len(args) >= 2:
            out.append(["prop", args[1], kwargs.get("text")])
        elif name == "label":
            out.append(["label", kwargs.get("text", args[0] if args else ""), kwargs.get("icon")])
        elif name in ("operator", "operator_menu_enum", "menu", "template_list"):
            out.append([name, *[a for a in args if isinstance(a, str)]])
    return out


def registration(tmp):
    from lamina.addon.ui import compat
    names = ["DATA_PT_lens", "DATA_PT_camera_dof", "DATA_PT_camera_dof_aperture", "RENDER_PT_format",
             "RENDER_PT_output", "RENDER_PT_color_management", "MATERIAL_PT_preview",
             "EEVEE_MATERIAL_PT_context_material", "DATA_PT_light", "RENDER_PT_freestyle"]
    found = {n: "LAMINA" in getattr(bpy.types, n).COMPAT_ENGINES for n in names if hasattr(bpy.types, n)}
    engines = [e.__name__ for e in bpy.types.RenderEngine.__subclasses__()]
    bpy.context.scene.render.engine = "LAMINA"          # raises if the engine is unknown
    engine_items = [bpy.context.scene.render.engine]
    import addon_utils
    addon_utils.disable("lamina", default_set=True)
    after_disable = {n: "LAMINA" in getattr(bpy.types, n).COMPAT_ENGINES for n in found}
    still_prop = hasattr(bpy.types.Material, "lamina")
    addon_utils.enable("lamina", default_set=True, handle_error=None)
    return {"compat": found, "engines": engines, "engine_items": engine_items, "after_disable": after_disable,
            "prop_after_disable": still_prop, "reenabled": hasattr(bpy.types.Material, "lamina")}


def compositor_sockets(tmp):
    """The Render Layers node offers the passes the Denoise node needs."""
    sc = bpy.context.scene
    sc.render.engine = "LAMINA"
    tree = bpy.data.node_groups.new("Comp", "CompositorNodeTree")
    sc.compositing_node_group = tree
    layers = tree.nodes.new("CompositorNodeRLayers")
    bpy.context.view_layer.update_render_passes()
    return [o.name for o in layers.outputs if o.enabled]


def operators(tmp):
    mat = bpy.data.materials.new("Ops")
    kinds = []
    with bpy.context.temp_override(material=mat):
        bpy.ops.lamina.stack_new()
        kinds.append([l.kind for l in mat.lamina.layers])
        mat.lamina.active_layer = 0
        bpy.ops.lamina.stack_add(kind="NULL")           # below the active (top) one
        kinds.append([l.kind for l in mat.lamina.layers])
        layer = mat.lamina.layers[mat.lamina.active_layer]
        layer.sigma_t, layer.thickness, layer.phase, layer.hg_g = 2.0, 0.5, "HG", 0.3
        bpy.ops.lamina.stack_duplicate()
        dup = mat.lamina.layers[mat.lamina.active_layer]
        dup_values = [dup.kind, dup.sigma_t, dup.thickness, dup.phase, round(dup.hg_g, 6)]
        kinds.append([l.kind for l in mat.lamina.layers])
        mat.lamina.active_layer = 3
        bpy.ops.lamina.stack_move(direction="UP")
        kinds.append([l.kind for l in mat.lamina.layers])
        active_after_move = mat.lamina.active_layer
        bpy.ops.lamina.stack_move(direction="DOWN")
        kinds.append([l.kind for l in mat.lamina.layers])
        bpy.ops.lamina.stack_remove()
        kinds.append([l.kind for l in mat.lamina.layers])
        mat.lamina.active_layer = 0
        moved_top_up = bpy.ops.lamina.stack_move(direction="UP")
    return {"kinds": kinds, "dup": dup_values, "active_after_move": active_after_move,
            "top_up": list(moved_top_up), "names": [l.name for l in mat.lamina.layers]}


def stack_panel(tmp):
    from lamina.addon.ui import material as ui
    mat = build.reference_stack(bpy.data.materials.new("Ref"))
    mat.lamina.active_layer = 0
    log = []
    ui.draw_stack(Recorder(log), mat)
    good = {"calls": _calls(log), "findings": ui.stack_findings(mat)}
    # An odd stack: a conductor that is not last.
    odd = bpy.data.materials.new("Odd")
    from lamina.addon.ops.stack import add_layer
    add_layer(odd.lamina, "CONDUCTOR", 0)
    add_layer(odd.lamina, "DIELECTRIC", 1)
    odd.lamina.use_stack = True
    log = []
    ui.draw_stack(Recorder(log), odd)
    # The list rows.
    row_log = []
    ui.LAMINA_UL_layers.draw_item(None, None, Recorder(row_log), mat.lamina, mat.lamina.layers[0], 0,
                                  mat.lamina, "active_layer", 0)
    poll = {
        "lamina": ui.LAMINA_PT_material_surface.poll(SimpleNamespace(engine="LAMINA", material=mat)),
        "cycles": ui.LAMINA_PT_material_surface.poll(SimpleNamespace(engine="CYCLES", material=mat)),
        "none": ui.LAMINA_PT_material_surface.poll(SimpleNamespace(engine="LAMINA", material=None)),
    }
    # A node material shows the node view and its unsupported nodes.
    nodes = bpy.data.materials.new("Nodes")
    nodes.use_nodes = True
    noise = nodes.node_tree.nodes.new("ShaderNodeTexNoise")
    nodes.node_tree.links.new(noise.outputs[0], nodes.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    node_log = []
    ui.draw_nodes(Recorder(node_log), nodes)
    cycle = bpy.data.materials.new("Cycle")
    add_layer(cycle.lamina, "DIELECTRIC", 0)
    nested = add_layer(cycle.lamina, "MATERIAL", 1)
    cycle.lamina.use_stack = True
    nested.material = cycle
    return {"good": good, "odd_calls": _calls(log), "odd_findings": ui.stack_findings(odd),
            "row": _calls(row_log), "poll": poll, "node_calls": _calls(node_log),
            "cycle_findings": ui.stack_findings(cycle)}


def light_and_render_panels(tmp):
    from lamina.addon.ui import light as light_ui
    from lamina.addon.ui import render as render_ui
    from lamina.addon.export.lights import ies_json
    out = {}
    for kind in ("POINT", "SPOT", "SUN", "AREA"):
        light = bpy.data.lights.new(kind, kind)
        log = []
        light_ui.draw_light(Recorder(log), light)
        if kind == "AREA":
            light.lamina.beam_mode = "CONE"
            light_ui.draw_area_beam(Recorder(log), light)
        if kind in ("POINT", "SPOT"):
            light_ui.draw_ies(Recorder(log), light)
        out[kind] = _calls(log)
    # Beam width is clamped to the cutoff.
    area = bpy.data.lights["AREA"]
    area.lamina.cutoff_angle = 0.3
    area.lamina.beam_width = 0.5
    out["beam_clamped"] = round(area.lamina.beam_width, 6)
    # A Cycles IES Texture node (internal text) is picked up.
    light = bpy.data.lights.new("IESLamp", "POINT")
    light.use_nodes = True
    text = bpy.data.texts.new("profile.ies")
    text.write("IESNA:LM-63-2002\nTILT=NONE\n")
    node = light.node_tree.nodes.new("ShaderNodeTexIES")
    node.mode = "INTERNAL"
    node.ies = text
    notes = []
    out["ies_node"] = ies_json(light, notes)
    log = []
    settings = bpy.context.scene.lamina
    for fn in (render_ui.draw_sampling, render_ui.draw_light_paths, render_ui.draw_film,
               render_ui.draw_performance, render_ui.draw_advanced):
        fn(Recorder(log), settings)
    out["render"] = _calls(log)
    out["unknown_icons"] = _icons_unknown()
    return out


def presets(tmp):
    from lamina.addon.export.images import ImageExporter
    from lamina.addon.export.stack import stack_json
    from lamina.addon.ops.presets import material_from_json
    src = build.reference_stack(bpy.data.materials.new("Src"))
    src.lamina.layers[1].use_anisotropy = True
    src.lamina.layers[1].roughness_v = 0.4
    src.lamina.layers[0].phase = "HG"
    src.lamina.layers[0].hg_g = -0.3
    src.lamina.emission_strength = 2.0
    src.lamina.emission_color = (1.0, 0.5, 0.25)
    doc = stack_json(src, ImageExporter(None, False, []))
    dst = bpy.data.materials.new("Dst")
    material_from_json(dst, doc, Path(tmp))
    again = stack_json(dst, ImageExporter(None, False, []))
    # Through the operator, from a preset file.
    preset = Path(tmp) / "coated-copper.json"
    preset.write_text(json.dumps({"name": "Coated copper", "category": "Metal", "description": "",
                                  "tags": [], "material": doc}))
    applied = bpy.data.materials.new("Applied")
    with bpy.context.temp_override(material=applied):
        status = bpy.ops.lamina.preset_apply(filepath=str(preset))
    from_op = stack_json(applied, ImageExporter(None, False, []))
    return {"doc": doc, "again": again, "status": list(status), "from_op": from_op}
