"""World properties: the surface node view, or the world colour without nodes."""
from __future__ import annotations

import bpy

from ..export.images import ImageExporter
from ..export.world import _tree, world_json
from .base import LaminaPanel, draw_findings


def draw_world(layout, world) -> None:
    tree = _tree(world)
    if tree is None:
        layout.prop(world, "color")
        return
    output = tree.get_output_node("CYCLES") or tree.get_output_node("ALL")
    if output is None:
        layout.label(text="No World Output node", icon="ERROR")
        return
    layout.template_node_view(tree, output, output.inputs["Surface"])
    notes: list[str] = []
    world_json(world, ImageExporter(None, False, notes), notes)
    draw_findings(layout, [("WARNING", n) for n in notes])


class LAMINA_PT_world_surface(LaminaPanel, bpy.types.Panel):
    bl_label = "Surface"
    bl_context = "world"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and getattr(context, "world", None) is not None

    def draw(self, context):
        draw_world(self.layout, context.world)


CLASSES = (LAMINA_PT_world_surface,)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
