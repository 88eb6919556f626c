"""``Material.lamina``: the layer stack and material-level settings."""
from __future__ import annotations

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, PointerProperty, StringProperty)
from bpy.types import PropertyGroup

from .layer import LaminaLayer


class LaminaMaterialSettings(PropertyGroup):
    use_stack: BoolProperty(
        name="Layer Stack", default=False,
        description="Render this material with its Lamina layer stack instead of translating its "
                    "shader nodes")
    layers: CollectionProperty(type=LaminaLayer, name="Interfaces")
    active_layer: IntProperty(name="Active Interface", default=0, min=0)
    emission_color: FloatVectorProperty(name="Emission", subtype='COLOR', size=3,
                                        default=(1.0, 1.0, 1.0), min=0.0, max=1.0)
    emission_strength: FloatProperty(name="Strength", default=0.0, min=0.0, soft_max=100.0,
                                     description="Emitted radiance (W m⁻² sr⁻¹) = colour × strength; "
                                                 "0 = not a light")
    emission_sides: EnumProperty(
        name="Emit From", default="BOTH",
        items=(("BOTH", "Both Sides", "Both faces emit (as Cycles)", 0),
               ("FRONT", "Front Side", "Only the front face emits (the side its normals point to); "
                                       "the back is black and lights nothing", 1)),
        description="Which faces of an emissive surface emit light: the stack's emission and the "
                    "emission of its shader nodes (Emission shader, Principled Emission)")
    # The preset this stack came from (addon/export/preset_link.py). While the stack is unchanged
    # since then (same fingerprint), export writes the preset's material JSON exactly, so
    # fields the stack editor cannot show are kept; an edit detaches it.
    preset_name: StringProperty(name="Preset", default="", options={'HIDDEN'},
                                description="Name of the preset this stack was loaded from")
    preset_label: StringProperty(name="Preset Label", default="", options={'HIDDEN'})
    preset_file: StringProperty(name="Preset File", default="", options={'HIDDEN'},
                                description="Where the preset was read from (texture paths are relative to it)")
    preset_material: StringProperty(name="Preset Material", default="", options={'HIDDEN'},
                                     description="The preset's material JSON, exactly as in its file")
    preset_fingerprint: StringProperty(name="Preset Fingerprint", default="", options={'HIDDEN'},
                                       description="The stack's JSON right after the preset was applied")
    preset_dropped: StringProperty(name="Preset Fields Not Editable", default="", options={'HIDDEN'},
                                   description="Preset fields the stack editor cannot represent (JSON list)")


CLASSES = (LaminaMaterialSettings,)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Material.lamina = PointerProperty(type=LaminaMaterialSettings)


def unregister():
    del bpy.types.Material.lamina
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
