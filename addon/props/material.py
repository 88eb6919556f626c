"""``Material.lamina``: the layer stack and material-level settings."""
from __future__ import annotations

import bpy
from bpy.props import (BoolProperty, CollectionProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, PointerProperty)
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


CLASSES = (LaminaMaterialSettings,)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Material.lamina = PointerProperty(type=LaminaMaterialSettings)


def unregister():
    del bpy.types.Material.lamina
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
