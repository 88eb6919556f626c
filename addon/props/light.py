"""``Light.lamina``: IES profile and the directional-area-light cone.

Strength, colour, temperature, exposure, size and spread are Blender's own light properties
(exported with Cycles ≥ 4.0 units); only what Blender lacks is stored here.
"""
from __future__ import annotations

import math

import bpy
from bpy.props import EnumProperty, FloatProperty, PointerProperty, StringProperty
from bpy.types import PropertyGroup

IES_MODES = (
    ("NONE", "None", "No profile (or the IES Texture node of the light's Cycles node tree, if any)", 0),
    ("FILE", "File", "An external LM-63 .ies file", 1),
    ("TEXT", "Text", "A Text data-block holding LM-63 data (saved inside the .blend)", 2),
)

BEAM_MODES = (
    ("SPREAD", "Spread", "Blender's area-light Spread angle (as Cycles)", 0),
    ("CONE", "Beam / Cutoff", "Full radiance inside Beam Width, none beyond Cutoff, smooth in between", 1),
)


def _beam_update(self, context):
    # Keep the cone well-formed: the full-radiance beam cannot be wider than the cutoff.
    if self.beam_width > self.cutoff_angle:
        self.beam_width = self.cutoff_angle


class LaminaLightSettings(PropertyGroup):
    ies_mode: EnumProperty(name="IES Profile", items=IES_MODES, default="NONE",
                           description="Photometric (LM-63) profile for point and spot lights")
    ies_file: StringProperty(name="IES File", subtype='FILE_PATH',
                             description="LM-63 .ies file (a path relative to the .blend is allowed)")
    ies_text: PointerProperty(name="IES Text", type=bpy.types.Text,
                              description="Text data-block with LM-63 content")
    beam_mode: EnumProperty(name="Directionality", items=BEAM_MODES, default="SPREAD",
                            description="How the emission of an area light falls off with the angle "
                                        "to its normal")
    cutoff_angle: FloatProperty(name="Cutoff", subtype='ANGLE', default=math.radians(60.0),
                                min=0.0, max=math.radians(90.0), update=_beam_update,
                                description="No emission beyond this angle from the normal")
    beam_width: FloatProperty(name="Beam Width", subtype='ANGLE', default=math.radians(30.0),
                              min=0.0, max=math.radians(90.0), update=_beam_update,
                              description="Full radiance within this angle from the normal")


CLASSES = (LaminaLightSettings,)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Light.lamina = PointerProperty(type=LaminaLightSettings)


def unregister():
    del bpy.types.Light.lamina
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
