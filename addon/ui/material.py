"""Material properties: the layer-stack editor, or the translated node tree.

Panels are thin; ``draw_*`` functions take (layout, data) so they can be tested without a UI.
"""
from __future__ import annotations

import bpy

from ...backend.layered.phase_schema import BY_ENUM, label_of
from ..constants import INTERFACE_KINDS
from ..export import preset_link
from ..export.images import ImageExporter
from ..export.nodes import NodeTranslator
from ..export.stack import StackError, alpha, is_clear, stack_json
from ..presets import library
from ..stack_check import check_material
from .base import LaminaPanel, draw_findings

KIND_ICONS = {item[0]: item[3] for item in INTERFACE_KINDS}
MAX_DROPPED_SHOWN = 6
KIND_LABELS = {item[0]: item[1] for item in INTERFACE_KINDS}


# ------------------------------------------------------------------ summaries (also used by tests)

def interface_summary(layer) -> str:
    kind = layer.kind
    if kind == "DIELECTRIC":
        return f"IOR {layer.ior:.3g} · r {layer.roughness:.2g}"
    if kind == "CONDUCTOR":
        metal = "η,k" if layer.metal == "CUSTOM" else layer.metal
        return f"{metal} · r {layer.roughness:.2g}"
    if kind == "DIFFUSE":
        return "Lambert" + (" · tex" if layer.color_texture else "")
    if kind == "MATERIAL":
        return layer.material.name if layer.material else "(none)"
    return "pass-through"


def optical_depth(layer) -> str:
    if layer.use_chromatic:
        return "(" + ", ".join(f"{s * layer.thickness:.3g}" for s in layer.sigma_t_rgb) + ")"
    return f"{layer.sigma_t * layer.thickness:.3g}"


def medium_summary(layer) -> str:
    if is_clear(layer):
        return "clear"
    kind = BY_ENUM[layer.phase]
    phase = kind.summary.format(**{p.prop: getattr(layer, p.prop) for p in kind.params})
    return f"τ {optical_depth(layer)} · {phase}"


def stack_findings(material) -> list[tuple[str, str]]:
    """What the panel warns about: export errors and odd-stack checks on the exported JSON."""
    notes: list[str] = []
    try:
        images = ImageExporter(None, False, notes)
        doc = stack_json(material, images, linked=preset_link.linked_json(images))
    except StackError as exc:
        return [("ERROR", str(exc))]
    return check_material(doc) + [("WARNING", n) for n in notes]


# ------------------------------------------------------------------ list

class LAMINA_UL_layers(bpy.types.UIList):
    """One row per interface; the medium below it is summarised at the right (▼)."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0,
                  flt_flag=0):
        row = layout.row(align=True)
        row.prop(item, "name", text="", emboss=False, icon=KIND_ICONS.get(item.kind, "DOT"))
        sub = row.row()
        sub.alignment = "RIGHT"
        sub.label(text=interface_summary(item))
        if index < len(data.layers) - 1:
            sub.label(text="▼ " + medium_summary(item))


# ------------------------------------------------------------------ draw functions

def _texture_row(layout, layer, value_prop: str, texture_prop: str, text: str | None = None) -> None:
    row = layout.row(align=True)
    if text is None:
        row.prop(layer, value_prop)
    else:
        row.prop(layer, value_prop, text=text)
    row.prop(layer, texture_prop, text="", icon="IMAGE_DATA")


def draw_interface(layout, layer, index: int) -> None:
    box = layout.box()
    head = box.row()
    head.label(text=f"Interface {index + 1}", icon=KIND_ICONS.get(layer.kind, "DOT"))
    head.prop(layer, "kind", text="")
    col = box.column()
    col.use_property_split = True
    col.use_property_decorate = False
    kind = layer.kind
    if kind == "DIELECTRIC":
        col.prop(layer, "ior")
    elif kind == "CONDUCTOR":
        col.prop(layer, "metal")
        if layer.metal == "CUSTOM":
            col.prop(layer, "eta")
            col.prop(layer, "k")
        col.prop(layer, "tint")
    elif kind == "DIFFUSE":
        _texture_row(col, layer, "color", "color_texture")
    elif kind == "MATERIAL":
        col.prop(layer, "material")
    if kind in ("DIELECTRIC", "CONDUCTOR"):
        _texture_row(col, layer, "roughness", "roughness_texture")
        col.prop(layer, "use_anisotropy")
        if layer.use_anisotropy:
            col.prop(layer, "roughness_v")
        col.prop(layer, "distribution")
        col.prop(layer, "masking")
        if layer.roughness_texture:
            col.prop(layer, "roughness_texture_alpha")
        texture = (" (× texture)" if layer.roughness_texture_alpha else " (× texture²)") \
            if layer.roughness_texture else ""
        col.label(text=f"α = r² = {alpha(layer.roughness):.4g}{texture}")
    if kind != "MATERIAL":
        draw_surface_detail(box, layer)


def draw_surface_detail(layout, layer) -> None:
    """The interface's own normal and bump maps (Blender's Normal Map and Bump nodes)."""
    col = layout.column()
    col.use_property_split = True
    col.use_property_decorate = False
    col.prop(layer, "normal_texture")
    if layer.normal_texture:
        col.prop(layer, "normal_strength")
    col.prop(layer, "bump_texture")
    if layer.bump_texture:
        col.prop(layer, "bump_distance")
        col.prop(layer, "bump_strength")
        col.prop(layer, "bump_invert")


def draw_medium(layout, layer, index: int) -> None:
    box = layout.box()
    box.label(text=f"Medium between interfaces {index + 1} and {index + 2}", icon="MOD_OCEAN")
    col = box.column()
    col.use_property_split = True
    col.use_property_decorate = False
    _texture_row(col, layer, "thickness", "thickness_texture")
    col.prop(layer, "use_chromatic")
    _texture_row(col, layer, "sigma_t_rgb" if layer.use_chromatic else "sigma_t", "sigma_t_texture")
    if not is_clear(layer):
        _texture_row(col, layer, "albedo", "albedo_texture")
        col.prop(layer, "phase")
        kind = BY_ENUM[layer.phase]
        choices = {p.key: getattr(layer, p.prop).lower() for p in kind.params if p.kind == "choice"}
        for p in kind.params:                       # its row in backend/layered/phase_schema.py
            if p.kind == "axis":
                _texture_row(col, layer, p.prop, p.texture_prop, text=label_of(p, choices))
            else:
                col.prop(layer, p.prop)
        col.label(text=f"Optical depth τ = σt·d = {optical_depth(layer)}")


def draw_stack(layout, material) -> None:
    settings = material.lamina
    row = layout.row(align=True)
    row.prop(settings, "use_stack")
    row.menu("LAMINA_MT_material_presets", text="Presets", icon="PRESET")
    if not settings.use_stack:
        return
    draw_preset_link(layout, material)
    row = layout.row()
    row.template_list("LAMINA_UL_layers", "", settings, "layers", settings, "active_layer", rows=4)
    col = row.column(align=True)
    col.operator_menu_enum("lamina.stack_add", "kind", text="", icon="ADD")
    col.operator("lamina.stack_remove", text="", icon="REMOVE")
    col.operator("lamina.stack_duplicate", text="", icon="DUPLICATE")
    col.separator()
    col.operator("lamina.stack_move", text="", icon="TRIA_UP").direction = "UP"
    col.operator("lamina.stack_move", text="", icon="TRIA_DOWN").direction = "DOWN"

    n = len(settings.layers)
    if n == 0:
        layout.label(text="Add an interface to start the stack", icon="INFO")
        return
    index = min(settings.active_layer, n - 1)
    layer = settings.layers[index]
    draw_interface(layout, layer, index)
    if index < n - 1:
        draw_medium(layout, layer, index)
    draw_findings(layout, stack_findings(material))


def draw_preset_link(layout, material) -> None:
    """Which preset the stack came from, and whether export still writes it exactly."""
    settings = material.lamina
    state = preset_link.state(material)
    if state == preset_link.NONE:
        return
    dropped = preset_link.dropped(material)
    label = settings.preset_label or settings.preset_name
    box = layout.box()
    col = box.column(align=True)
    row = col.row(align=True)
    if state == preset_link.EXACT:
        row.label(text=f"Preset: {label}", icon="LINKED")
        if dropped:
            col.label(text=f"{len(dropped)} preset field(s) not editable here, rendered from the preset:",
                      icon="INFO")
    else:
        row.label(text=f"Edited since preset: {label}", icon="UNLINKED")
        if dropped:
            col.label(text=f"{len(dropped)} preset field(s) no longer rendered:", icon="ERROR")
        op = row.operator("lamina.preset_apply", text="", icon="FILE_REFRESH")
        op.name = settings.preset_name
        path = preset_link.preset_path(settings) if settings.preset_file else None
        op.filepath = str(path) if path is not None and path.is_file() else ""
    row.operator("lamina.preset_detach", text="", icon="X")
    for field in dropped[:MAX_DROPPED_SHOWN]:
        col.label(text="    " + field)
    if len(dropped) > MAX_DROPPED_SHOWN:
        col.label(text=f"    and {len(dropped) - MAX_DROPPED_SHOWN} more")


def draw_preset_browser(layout, context) -> None:
    wm = context.window_manager
    layout.template_icon_view(wm, "lamina_preset_browser", show_labels=True, scale=6.0, scale_popup=5.0)
    entry = next((e for e in library.entries() if e.name == wm.lamina_preset_browser), None)
    if entry is None:
        return
    col = layout.column(align=True)
    col.label(text=f"{entry.label} · {entry.category}" + (" · user" if entry.user else ""))
    if entry.error:
        col.label(text=entry.error, icon="ERROR")
    row = layout.row(align=True)
    op = row.operator("lamina.preset_apply", text="Apply to Material", icon="IMPORT")
    op.name = entry.name
    op.filepath = str(entry.path)
    if entry.user:
        row.operator("lamina.preset_delete", text="", icon="TRASH").name = entry.name


def draw_emission(layout, material) -> None:
    settings = material.lamina
    col = layout.column()
    col.use_property_split = True
    col.prop(settings, "emission_color")
    col.prop(settings, "emission_strength")
    col.prop(settings, "emission_sides")


def node_findings(material) -> list[tuple[str, str]]:
    notes: list[str] = []
    NodeTranslator(ImageExporter(None, False, notes), notes).material(material)
    prefix = f"material '{material.name}': "
    return [("WARNING", n[len(prefix):] if n.startswith(prefix) else n) for n in dict.fromkeys(notes)]


def draw_nodes(layout, material) -> None:
    row = layout.row(align=True)
    row.operator("lamina.stack_new", icon="NODE_COMPOSITING")
    row.menu("LAMINA_MT_material_presets", text="Presets", icon="PRESET")
    tree = material.node_tree
    if tree is None:
        layout.prop(material, "diffuse_color", text="Color")
        return
    output = tree.get_output_node("CYCLES") or tree.get_output_node("ALL")
    if output is None:
        layout.label(text="No Material Output node", icon="ERROR")
        return
    layout.template_node_view(tree, output, output.inputs["Surface"])
    col = layout.column()
    col.use_property_split = True
    col.prop(material.lamina, "emission_sides", text="Emission From")
    draw_findings(layout, node_findings(material))
    from ..ops.bake import bakeable_inputs
    if bakeable_inputs(material):
        op = layout.operator("lamina.bake_procedurals", icon="TEXTURE")
        op.material = material.name


# ------------------------------------------------------------------ panels

class LAMINA_PT_material_surface(LaminaPanel, bpy.types.Panel):
    bl_label = "Surface"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and getattr(context, "material", None) is not None

    def draw(self, context):
        material = context.material
        if material.lamina.use_stack:
            draw_stack(self.layout, material)
        else:
            draw_nodes(self.layout, material)


class _StackSubPanel(LaminaPanel):
    """A closed sub-panel of Surface, shown while the material uses its layer stack."""
    bl_context = "material"
    bl_parent_id = "LAMINA_PT_material_surface"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        mat = getattr(context, "material", None)
        return super().poll(context) and mat is not None and mat.lamina.use_stack


class LAMINA_PT_material_emission(_StackSubPanel, bpy.types.Panel):
    bl_label = "Stack Emission"

    def draw(self, context):
        draw_emission(self.layout, context.material)


class LAMINA_PT_material_viewport(_StackSubPanel, bpy.types.Panel):
    """What other engines show for the stack (ops/viewport_colour.py)."""
    bl_label = "Viewport Colour"

    def draw(self, context):
        col = self.layout.column()
        col.label(text="Cycles, EEVEE and Solid mode show an approximation:", icon="INFO")
        col.prop(context.material, "diffuse_color", text="Measured Colour")
        col.operator("lamina.viewport_colour", icon="FILE_REFRESH")


class LAMINA_PT_material_presets(LaminaPanel, bpy.types.Panel):
    bl_label = "Preset Library"
    bl_context = "material"
    bl_parent_id = "LAMINA_PT_material_surface"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return super().poll(context) and getattr(context, "material", None) is not None

    def draw_header(self, context):
        self.layout.label(text="", icon="ASSET_MANAGER")

    def draw(self, context):
        draw_preset_browser(self.layout, context)


CLASSES = (LAMINA_UL_layers, LAMINA_PT_material_surface, LAMINA_PT_material_emission,
           LAMINA_PT_material_viewport, LAMINA_PT_material_presets)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
