"""One entry of a material's layer stack: an interface and the medium below it.

A stack of N entries is N interfaces (0 = top, facing the viewer) with N−1 media: the medium of
entry i lies between interfaces i and i+1, so the medium fields of the last entry are unused.
Roughness is Blender's perceptual roughness r (the microfacet α = r² is written to files, as
Cycles does); angles and colours follow Blender's conventions, colours are linear RGB.
"""
from __future__ import annotations

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       PointerProperty, StringProperty)
from bpy.types import PropertyGroup

from ...backend.layered.phase_schema import PHASES
from ..constants import DISTRIBUTIONS, INTERFACE_KINDS, MASKINGS, METALS

# Phase functions: one row each in backend/layered/phase_schema.py (the enum's numbers are what
# saved .blend files hold).
PHASE_KINDS = tuple((k.enum, k.label, k.description, k.number) for k in PHASES)

METAL_ITEMS = [(sym, f"{name} ({sym})", f"Measured complex IOR of {name.lower()}", i)
               for i, (sym, name) in enumerate(METALS)]
METAL_ITEMS.append(("CUSTOM", "Custom (η, k)", "Explicit complex index of refraction per RGB channel", 99))


def _nested_poll(self, material):
    # Only materials that have a stack can be nested; a cycle is caught by the stack checks.
    settings = getattr(material, "lamina", None)
    return bool(settings and settings.use_stack and len(settings.layers))


def _image_prop(name: str, what: str):
    return PointerProperty(name=name, type=bpy.types.Image,
                           description=f"Image texture (UV-mapped, active UV map) for {what}")


class LaminaLayer(PropertyGroup):
    name: StringProperty(name="Name", description="Label of this interface in the stack")

    kind: EnumProperty(name="Interface", items=INTERFACE_KINDS, default="DIELECTRIC",
                       description="What kind of boundary this interface is")

    # --- dielectric
    ior: FloatProperty(name="IOR", default=1.5, min=0.01, max=10.0, soft_min=1.0, soft_max=3.0,
                       precision=3, step=1,
                       description="Index of refraction of the medium below this interface "
                                   "(the index above is that of the interface above; 1.0 above the top)")

    # --- shared microfacet parameters (dielectric, conductor)
    roughness: FloatProperty(name="Roughness", default=0.1, min=0.0, max=1.0, subtype='FACTOR',
                             description="Perceptual roughness r as in Blender; the microfacet "
                                         "α = r² is exported. 0 = perfectly smooth (a delta lobe)")
    use_anisotropy: BoolProperty(name="Anisotropic", default=False,
                                 description="Separate roughness along the UV tangent (u) and across it (v)")
    roughness_v: FloatProperty(name="Roughness V", default=0.1, min=0.0, max=1.0, subtype='FACTOR',
                               description="Perceptual roughness across the UV tangent (α_v = r_v²)")
    distribution: EnumProperty(name="Distribution", items=DISTRIBUTIONS, default="GGX")
    masking: EnumProperty(name="Masking", items=MASKINGS, default="HEIGHT_CORRELATED",
                          description="Microfacet masking-shadowing form")
    roughness_texture: _image_prop("Roughness Texture", "the roughness (stores r; squared on export)")
    roughness_texture_alpha: BoolProperty(
        name="Texture Holds α", default=False,
        description="The roughness texture stores the microfacet α itself (as preset files do), "
                    "not Blender's roughness r: it is not squared on export")

    # --- conductor
    metal: EnumProperty(name="Metal", items=METAL_ITEMS, default="Cu",
                        description="Named metal, or Custom for an explicit complex IOR")
    eta: FloatVectorProperty(name="η", size=3, default=(0.2, 0.92, 1.1), min=0.0, soft_max=5.0,
                             description="Real part of the complex IOR per RGB channel, relative to the medium above")
    k: FloatVectorProperty(name="k", size=3, default=(3.9, 2.45, 2.14), min=0.0, soft_max=10.0,
                           description="Imaginary part (extinction) of the complex IOR per RGB channel")
    tint: FloatVectorProperty(name="Tint", subtype='COLOR', size=3, default=(1.0, 1.0, 1.0),
                              min=0.0, max=1.0,
                              description="Artistic multiplier on the metal's reflectance (white = physical)")

    # --- diffuse
    color: FloatVectorProperty(name="Color", subtype='COLOR', size=3, default=(0.8, 0.8, 0.8),
                               min=0.0, max=1.0, description="Diffuse albedo (linear RGB)")
    color_texture: _image_prop("Color Texture", "the diffuse colour (multiplied by Color)")

    # --- surface detail of the interface (not of a nested material: its own interfaces have theirs)
    normal_texture: _image_prop("Normal Map", "this interface's tangent-space normal map (RGB·2 − 1, "
                                              "a Non-Color image, as Blender's Normal Map node)")
    normal_strength: FloatProperty(name="Normal Strength", default=1.0, min=0.0, soft_max=1.0, max=10.0,
                                   description="Mix between the surface normal (0) and the mapped one "
                                               "(1), as the Normal Map node's Strength")
    bump_texture: _image_prop("Bump Height", "this interface's height for bump mapping (its luminance, "
                                             "as the Bump node's Height fed by an image)")
    bump_distance: FloatProperty(name="Bump Distance", default=1.0, soft_min=0.0, soft_max=1.0, precision=3,
                                 description="Height multiplier in scene units, as the Bump node's Distance")
    bump_strength: FloatProperty(name="Bump Strength", default=1.0, min=0.0, max=1.0, subtype='FACTOR',
                                 description="Mix between the unbumped (0) and the bumped normal (1)")
    bump_invert: BoolProperty(name="Invert Bump", default=False,
                              description="Dents where the height rises, as the Bump node's Invert")

    # --- nested material
    material: PointerProperty(name="Material", type=bpy.types.Material, poll=_nested_poll,
                              description="A material with a Lamina stack, used as this interface")

    # --- medium below this interface
    thickness: FloatProperty(name="Thickness", default=1.0, min=0.0, soft_max=10.0, precision=3,
                             description="Thickness of the medium below, in the length unit of σt "
                                         "(only the optical depth σt × thickness matters)")
    sigma_t: FloatProperty(name="Density σt", default=0.0, min=0.0, soft_max=20.0, precision=3,
                           description="Extinction coefficient per unit thickness; 0 = a clear "
                                       "layer that neither scatters nor absorbs")
    sigma_t_texture: _image_prop("Density Texture", "the extinction (multiplied by σt)")
    thickness_texture: _image_prop("Thickness Texture", "the thickness (multiplied by Thickness; "
                                                        "grey variation of the optical depth)")
    use_chromatic: BoolProperty(name="Chromatic Density", default=False,
                                description="A separate extinction per RGB channel (coloured "
                                            "absorption); slower than a grey density")
    sigma_t_rgb: FloatVectorProperty(name="Density σt (RGB)", size=3, default=(1.0, 1.0, 1.0),
                                     min=0.0, soft_max=20.0, precision=3,
                                     description="Extinction per unit thickness for each RGB channel")
    albedo: FloatVectorProperty(name="Albedo", subtype='COLOR', size=3, default=(0.8, 0.8, 0.8),
                                min=0.0, max=1.0,
                                description="Single-scattering albedo of the medium (1 = no absorption)")
    albedo_texture: _image_prop("Albedo Texture", "the medium albedo (multiplied by Albedo)")
    phase: EnumProperty(name="Phase Function", items=PHASE_KINDS, default="ISOTROPIC")
    orientation_texture: _image_prop("Axis Texture", "the fibre axis / flake normal, encoded like a "
                                                    "tangent-space normal map (RGB·2 − 1; non-colour data)")
    # Each phase function's parameters are added below from its schema row.


def _phase_property(param):
    """A phase parameter's property, from its row in backend/layered/phase_schema.py."""
    if param.kind == "choice":
        items = [(value.upper(), label, doc, i) for i, (value, label, doc) in enumerate(param.choices)]
        return EnumProperty(name=param.label, items=items, default=param.default.upper(),
                            description=param.description)
    default = param.default if param.ui_default is None else param.ui_default
    if param.kind == "axis":
        return FloatVectorProperty(name=param.label, default=tuple(default), description=param.description,
                                   **param.ui)
    return FloatProperty(name=param.label, default=default, description=param.description, **param.ui)


for _kind in PHASES:
    for _param in _kind.params:
        LaminaLayer.__annotations__.setdefault(_param.prop, _phase_property(_param))


CLASSES = (LaminaLayer,)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
