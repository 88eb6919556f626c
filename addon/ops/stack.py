"""Layer-stack editing: add, remove, duplicate, move; and turning a stack on."""
from __future__ import annotations

import bpy
from bpy.props import EnumProperty

from ..constants import INTERFACE_KINDS

_COPY_SKIP = {"rna_type"}


def _material(context):
    return getattr(context, "material", None)


def copy_layer(src, dst) -> None:
    """Copy every property of one LaminaLayer to another (pointers included)."""
    for prop in src.bl_rna.properties:
        name = prop.identifier
        if name in _COPY_SKIP or prop.is_readonly:
            continue
        setattr(dst, name, getattr(src, name))


def default_name(settings, kind: str) -> str:
    label = next(item[1] for item in INTERFACE_KINDS if item[0] == kind)
    used = {layer.name for layer in settings.layers}
    if label not in used:
        return label
    n = 2
    while f"{label} {n}" in used:
        n += 1
    return f"{label} {n}"


def add_layer(settings, kind: str = "DIELECTRIC", index: int | None = None):
    """Insert a new interface below ``index`` (default: below the active one); returns it."""
    layers = settings.layers
    layer = layers.add()
    layer.kind = kind
    layer.name = default_name(settings, kind)
    if kind == "DIFFUSE":
        layer.roughness = 0.0
    target = len(layers) - 1 if index is None else max(0, min(index, len(layers) - 1))
    layers.move(len(layers) - 1, target)
    settings.active_layer = target
    return layers[target]


def start_default_stack(settings) -> None:
    """A clear coat over a copper base: a useful first stack that shows what a stack is."""
    settings.layers.clear()
    coat = add_layer(settings, "DIELECTRIC", 0)
    coat.name = "Clear Coat"
    coat.ior = 1.5
    coat.roughness = 0.1
    coat.thickness = 1.0
    coat.sigma_t = 0.0
    base = add_layer(settings, "CONDUCTOR", 1)
    base.name = "Copper"
    base.metal = "Cu"
    base.roughness = 0.3
    settings.active_layer = 0
    settings.use_stack = True


class _StackOperator:
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return _material(context) is not None


class LAMINA_OT_stack_add(_StackOperator, bpy.types.Operator):
    bl_idname = "lamina.stack_add"
    bl_label = "Add Interface"
    bl_description = "Add an interface (with a medium) below the active one"

    kind: EnumProperty(name="Kind", items=INTERFACE_KINDS, default="DIELECTRIC")

    def execute(self, context):
        settings = _material(context).lamina
        if not settings.layers:
            add_layer(settings, self.kind, 0)
        else:
            add_layer(settings, self.kind, settings.active_layer + 1)
        settings.use_stack = True
        return {"FINISHED"}


class LAMINA_OT_stack_remove(_StackOperator, bpy.types.Operator):
    bl_idname = "lamina.stack_remove"
    bl_label = "Remove Interface"
    bl_description = "Remove the active interface and the medium below it"

    @classmethod
    def poll(cls, context):
        mat = _material(context)
        return mat is not None and len(mat.lamina.layers) > 0

    def execute(self, context):
        settings = _material(context).lamina
        index = min(settings.active_layer, len(settings.layers) - 1)
        settings.layers.remove(index)
        settings.active_layer = max(0, min(index, len(settings.layers) - 1))
        return {"FINISHED"}


class LAMINA_OT_stack_duplicate(_StackOperator, bpy.types.Operator):
    bl_idname = "lamina.stack_duplicate"
    bl_label = "Duplicate Interface"
    bl_description = "Duplicate the active interface (and its medium) below it"

    @classmethod
    def poll(cls, context):
        mat = _material(context)
        return mat is not None and len(mat.lamina.layers) > 0

    def execute(self, context):
        settings = _material(context).lamina
        index = min(settings.active_layer, len(settings.layers) - 1)
        src = settings.layers[index]
        dst = settings.layers.add()
        copy_layer(src, dst)
        dst.name = default_name(settings, src.kind) if src.name else ""
        settings.layers.move(len(settings.layers) - 1, index + 1)
        settings.active_layer = index + 1
        return {"FINISHED"}


class LAMINA_OT_stack_move(_StackOperator, bpy.types.Operator):
    bl_idname = "lamina.stack_move"
    bl_label = "Move Interface"
    bl_description = "Move the active interface (with its medium) up or down the stack"

    direction: EnumProperty(items=(("UP", "Up", "Towards the top", 0),
                                   ("DOWN", "Down", "Towards the bottom", 1)))

    @classmethod
    def poll(cls, context):
        mat = _material(context)
        return mat is not None and len(mat.lamina.layers) > 1

    def execute(self, context):
        settings = _material(context).lamina
        index = settings.active_layer
        target = index - 1 if self.direction == "UP" else index + 1
        if not (0 <= index < len(settings.layers) and 0 <= target < len(settings.layers)):
            return {"CANCELLED"}
        settings.layers.move(index, target)
        settings.active_layer = target
        return {"FINISHED"}


class LAMINA_OT_stack_new(_StackOperator, bpy.types.Operator):
    bl_idname = "lamina.stack_new"
    bl_label = "Use Layer Stack"
    bl_description = "Give this material a Lamina layer stack (a clear coat over copper to start with)"

    def execute(self, context):
        settings = _material(context).lamina
        if settings.layers:
            settings.use_stack = True
        else:
            start_default_stack(settings)
        return {"FINISHED"}


CLASSES = (LAMINA_OT_stack_add, LAMINA_OT_stack_remove, LAMINA_OT_stack_duplicate,
           LAMINA_OT_stack_move, LAMINA_OT_stack_new)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
