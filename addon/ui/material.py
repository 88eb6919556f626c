"""Material properties: the layer-stack editor, or the translated node tree.

Panels are thin; ``draw_*`` functions take (layout, data) so they can be tested without a UI.
"""
from __future__ import annotations

import bpy

from ..constants import INTERFACE_KINDS
from ..export.images import ImageExporter
from ..export.nodes import NodeTranslator
from ..export.stack import StackError, alpha, stack_json
from ..stack_check import check_material
from .base import LaminaPanel, draw_findings

KIND_ICONS = {item[0]: item[3] for item in INTERFACE_KINDS}
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


def medium_summary(layer) -> str:
    if layer.sigma_t == 0 and layer.sigma_t_texture is None:
        return "clear"
    tau = layer.sigma_t * layer.thickness
    phase = {"ISOTROPIC": "iso", "HG": f"g {layer.hg_g:.2g}", "MICROFLAKE": "fibres",
             "VMF": f"κ {layer.vmf_kappa:.3g}", "SGGX": "sggx"}[layer.phase]
    return f"τ {tau:.3g} · {phase}"


def stack_findings(material) -> list[tuple[str, str]]:
    """What the panel warns about: export errors and odd-stack checks on the exported JSON."""
    notes: list[str] = []
    try:
        doc = stack_json(material, ImageExporter(None, False, notes))
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
        col.label(text=f"α = r² = {alpha(layer.roughness):.4g}" +
                       (" (× texture²)" if layer.roughness_texture else ""))


def draw_medium(layout, layer, index: int) -> None:
    box = layout.box()
    box.label(text=f"Medium between interfaces {index + 1} and {index + 2}", icon="MOD_OCEAN")
    col = box.column()
    col.use_property_split = True
    col.use_property_decorate = False
    col.prop(layer, "thickness")
    _texture_row(col, layer, "sigma_t", "sigma_t_texture")
    if layer.sigma_t > 0 or layer.sigma_t_texture is not None:
        _texture_row(col, layer, "albedo", "albedo_texture")
        col.prop(layer, "phase")
        if layer.phase == "HG":
            col.prop(layer, "hg_g")
        elif layer.phase == "MICROFLAKE":
            col.prop(layer, "flake_stddev")
            col.prop(layer, "flake_orientation")
        elif layer.phase == "VMF":
            col.prop(layer, "vmf_kappa")
        elif layer.phase == "SGGX":
            col.prop(layer, "sggx_shape")
            col.prop(layer, "flake_orientation", text="Normal" if layer.sggx_shape == "FLAKE" else "Axis")
            col.prop(layer, "sggx_roughness")
        col.label(text=f"Optical depth τ = σt·d = {layer.sigma_t * layer.thickness:.4g}")


def draw_stack(layout, material) -> None:
    settings = material.lamina
    row = layout.row(align=True)
    row.prop(settings, "use_stack")
    row.menu("LAMINA_MT_material_presets", text="Presets", icon="PRESET")
    if not settings.use_stack:
        return
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


def draw_emission(layout, material) -> None:
    settings = material.lamina
    col = layout.column()
    col.use_property_split = True
    col.prop(settings, "emission_color")
    col.prop(settings, "emission_strength")


def node_findings(material) -> list[tuple[str, str]]:
    notes: list[str] = []
    NodeTranslator(ImageExporter(None, False, notes), notes).material(material)
    prefix = f"material '{material.name}': "
    return [("WARNING", n[len(prefix):] if n.startswith(prefix) else n) for n in dict.fromkeys(notes)]


def draw_nodes(layout, material) -> None:
    row = layout.row()
    row.operator("lamina.stack_new", icon="NODE_COMPOSITING")
    tree = material.node_tree
    if tree is None:
        layout.prop(material, "diffuse_color", text="Color")
        return
    output = tree.get_output_node("CYCLES") or tree.get_output_node("ALL")
    if output is None:
        layout.label(text="No Material Output node", icon="ERROR")
        return
    layout.template_node_view(tree, output, output.inputs["Surface"])
    draw_findings(layout, node_findings(material))


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


class LAMINA_PT_material_emission(LaminaPanel, bpy.types.Panel):
    bl_label = "Stack Emission"
    bl_context = "material"
    bl_parent_id = "LAMINA_PT_material_surface"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        mat = getattr(context, "material", None)
        return super().poll(context) and mat is not None and mat.lamina.use_stack

    def draw(self, context):
        draw_emission(self.layout, context.material)


CLASSES = (LAMINA_UL_layers, LAMINA_PT_material_surface, LAMINA_PT_material_emission)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
