"""What Cycles, EEVEE and Material Preview show for a layer stack: Principled BSDF inputs that
approximate it (no bpy; the nodes are written by ops/viewport_colour.py).

A stack renders only in Lamina. So that a .blend does not turn grey when the engine is switched,
the add-on keeps, beside the stack, a Principled BSDF whose Base Color is the stack's own measured
reflectance (the backend's ``bsdf albedo``, light arriving 30° from the normal, textures at their
constant or mid-grey value) and whose other inputs follow the stack's layers: Metallic for a metal
at the bottom, Roughness from the top interface (Blender's roughness is √α), Transmission for a
stack that lets most light through. An approximation by design (docs/blender.md): the colour and
brightness under uniform light come out close; the lobe shapes, coats and media do not.
"""
from __future__ import annotations

import math

#: The incidence the albedo is measured at (from the normal, degrees).
ALBEDO_THETA = 30.0
ALBEDO_SAMPLES = 20_000
GREY = 0.5       # what a texture stands for here (the constant of a textured field)


def constant_doc(value):
    """The material JSON with every texture reference replaced by its scale, or mid-grey: the
    backend measures one colour, and images the export writes later need not exist yet."""
    if isinstance(value, dict):
        if "texture" in value:
            scale = value.get("scale")
            if isinstance(scale, (int, float)) or (isinstance(scale, list) and scale
                                                    and all(isinstance(v, (int, float)) for v in scale)):
                return scale
            return GREY
        return {k: constant_doc(v) for k, v in value.items()}
    if isinstance(value, list):
        return [constant_doc(v) for v in value]
    return value


def _interfaces(doc: dict) -> list[dict]:
    if doc.get("type") == "layered":
        return [i for i in doc.get("interfaces", []) if isinstance(i, dict)]
    return [doc]


def _alpha(interface: dict) -> float:
    value = interface.get("roughness", 0.0)
    if isinstance(value, list) and value:
        value = sum(float(v) for v in value) / len(value)
    try:
        return min(max(float(value), 0.0), 1.0)
    except (TypeError, ValueError):
        return GREY


def principled_inputs(doc: dict, albedo: dict) -> dict:
    """{"base_color": (r, g, b), "metallic", "roughness", "transmission"} for the stack ``doc``
    (its material JSON) whose measured reflectance and transmittance are ``albedo`` (the
    backend's ``bsdf albedo --json``: "R", "T" per RGB channel)."""
    reflect = [min(max(float(v), 0.0), 1.0) for v in albedo.get("R", [GREY] * 3)]
    transmit = [min(max(float(v), 0.0), 1.0) for v in albedo.get("T", [0.0] * 3)]
    layers = _interfaces(doc)
    top = layers[0] if layers else {}
    bottom = layers[-1] if layers else {}
    metallic = 1.0 if bottom.get("type") == "conductor" else 0.0
    if top.get("type") in ("dielectric", "conductor"):
        roughness = math.sqrt(_alpha(top))
    else:
        roughness = 1.0                                     # a diffuse top: Lambert
    r_mean, t_mean = sum(reflect) / 3, sum(transmit) / 3
    transmission = t_mean / (r_mean + t_mean) if t_mean > r_mean and r_mean + t_mean > 0 else 0.0
    base = reflect if transmission == 0.0 else [min(r + t, 1.0) for r, t in zip(reflect, transmit)]
    return {"base_color": tuple(base), "metallic": metallic, "roughness": roughness,
            "transmission": transmission}
