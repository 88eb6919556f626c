"""Light properties: Blender's light fields (Cycles units) plus IES and the area-light cone."""
from __future__ import annotations

import bpy

from ..export.lights import ies_json, ies_peak
from .base import LaminaPanel


def _si(value: float, unit: str) -> str:
    for factor, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if abs(value) >= factor:
            return f"{value / factor:.3g} {prefix}{unit}"
    return f"{value:.3g} {unit}"


def draw_ies_peak(layout, light) -> None:
    """The profile's peak and what it makes of this light's power (Cycles' units), so that a
    strength that blows the image out is visible before rendering."""
    peak = ies_peak(light)
    if peak is None:
        return
    if "error" in peak:
        layout.label(text=f"IES: {peak['error']}", icon="ERROR")
        return
    col = layout.column(align=True)
    col.label(text=f"Profile peak: {peak['candela']:,.0f} cd", icon="LIGHT_SPOT")
    col.label(text=f"Peak intensity: {_si(peak['w_per_sr'], 'W/sr')} at {_si(peak['watts'], 'W')} "
                   f"(× colour; W/sr = W × cd / 177.83)")


def draw_light(layout, light) -> None:
    layout.row().prop(light, "type", expand=True)
    col = layout.column()
    col.use_property_split = True
    col.use_property_decorate = False
    if hasattr(light, "use_temperature"):
        row = col.row(align=True, heading="Temperature")
        row.prop(light, "use_temperature", text="")
        sub = row.row(align=True)
        sub.active = light.use_temperature
        sub.prop(light, "temperature", text="")
        col.prop(light, "color", text="Tint" if light.use_temperature else "Color")
    else:
        col.prop(light, "color")
    col.separator()
    col.prop(light, "energy", text="Strength" if light.type == "SUN" else "Power")
    if hasattr(light, "exposure"):
        col.prop(light, "exposure")
    if light.type in ("POINT", "SPOT"):
        col.prop(light, "shadow_soft_size", text="Radius")
    elif light.type == "SUN":
        col.prop(light, "angle")
    elif light.type == "AREA":
        if hasattr(light, "normalize"):
            col.prop(light, "normalize")
        col.prop(light, "shape")
        sub = col.column(align=True)
        if light.shape in ("SQUARE", "DISK"):
            sub.prop(light, "size")
        else:
            sub.prop(light, "size", text="Size X")
            sub.prop(light, "size_y", text="Y")


def draw_area_beam(layout, light) -> None:
    settings = light.lamina
    col = layout.column()
    col.use_property_split = True
    col.use_property_decorate = False
    col.prop(settings, "beam_mode")
    if settings.beam_mode == "SPREAD":
        col.prop(light, "spread")
    else:
        col.prop(settings, "beam_width")
        col.prop(settings, "cutoff_angle")


def draw_ies(layout, light) -> None:
    settings = light.lamina
    col = layout.column()
    col.use_property_split = True
    col.use_property_decorate = False
    col.prop(settings, "ies_mode")
    if settings.ies_mode == "FILE":
        col.prop(settings, "ies_file")
    elif settings.ies_mode == "TEXT":
        col.prop(settings, "ies_text")
    else:
        notes: list[str] = []
        found = ies_json(light, notes)
        if found is not None:
            source = found.get("file") or "text data-block"
            layout.label(text=f"Using the Cycles IES Texture node ({source})", icon="INFO")
    draw_ies_peak(layout, light)


class LAMINA_PT_light(LaminaPanel, bpy.types.Panel):
    bl_label = "Light"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and getattr(context, "light", None) is not None

    def draw(self, context):
        draw_light(self.layout, context.light)


class LAMINA_PT_light_beam(LaminaPanel, bpy.types.Panel):
    bl_label = "Directionality"
    bl_context = "data"
    bl_parent_id = "LAMINA_PT_light"

    @classmethod
    def poll(cls, context):
        light = getattr(context, "light", None)
        return super().poll(context) and light is not None and light.type == "AREA"

    def draw(self, context):
        draw_area_beam(self.layout, context.light)


class LAMINA_PT_light_ies(LaminaPanel, bpy.types.Panel):
    bl_label = "IES Profile"
    bl_context = "data"
    bl_parent_id = "LAMINA_PT_light"

    @classmethod
    def poll(cls, context):
        light = getattr(context, "light", None)
        return super().poll(context) and light is not None and light.type in ("POINT", "SPOT")

    def draw(self, context):
        draw_ies(self.layout, context.light)


CLASSES = (LAMINA_PT_light, LAMINA_PT_light_beam, LAMINA_PT_light_ies)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
