"""Images baked from procedural shader inputs: which input an image stands for, and whether the
nodes behind that input changed since.

Lamina renders image textures only. *Bake Procedural Textures* (ops/bake.py) has Cycles bake what
feeds an input (a Noise Texture into Base Color, a Math chain into Roughness, a Wave Texture into a
Bump node's Height...) into an image over the object's UV map, and records it on the material:
``material["lamina_baked"][key] = {"image": name, "signature": hash, "object": name}``, key =
``"<node name>/<input name>"``. The node translator (nodes.py) uses the image while the
signature of the nodes upstream of the input is unchanged, and names the input otherwise.
"""
from __future__ import annotations

import hashlib

import bpy

PROPERTY = "lamina_baked"

# Node properties that do not change what a node computes.
_LAYOUT = {"location", "location_absolute", "width", "height", "name", "label", "parent", "select",
           "show_options", "show_preview", "hide", "mute", "show_texture", "use_custom_color", "color",
           "bl_idname", "bl_label", "bl_description", "bl_icon", "bl_static_type", "bl_width_default",
           "bl_width_min", "bl_width_max", "bl_height_default", "bl_height_min", "bl_height_max",
           "warning_propagation", "dimensions", "type", "internal_links", "inputs", "outputs",
           "rna_type", "is_active_output", "target"}


def key(node, input_name: str) -> str:
    return f"{node.name}/{input_name}"


def _value(v):
    if hasattr(v, "__len__") and not isinstance(v, str):
        return tuple(_value(x) for x in v)
    if isinstance(v, float):
        return round(v, 7)
    if isinstance(v, bpy.types.ID):
        return ("ID", v.name)
    return v


def _node_settings(node) -> list:
    out = []
    for prop in node.bl_rna.properties:
        ident = prop.identifier
        if ident in _LAYOUT or prop.is_readonly and prop.type != "POINTER":
            continue
        value = getattr(node, ident, None)
        if prop.type == "POINTER":
            if isinstance(value, bpy.types.ID):
                out.append((ident, value.name))
            elif ident == "color_ramp" and value is not None:
                out.append((ident, value.interpolation, value.color_mode,
                            tuple((round(e.position, 7), _value(e.color)) for e in value.elements)))
            elif ident == "texture_mapping" and value is not None:
                out.append((ident, _value(value.translation), _value(value.rotation), _value(value.scale)))
            continue
        if prop.type in ("BOOLEAN", "INT", "FLOAT", "STRING", "ENUM"):
            out.append((ident, _value(value)))
    return out


def signature(socket) -> str:
    """A hash of what an input socket receives: every node upstream of it with its settings, its
    unconnected input values and its links."""
    parts, seen, stack = [], set(), []
    for link in socket.links:
        if link.is_valid and not link.is_muted:
            parts.append(("in", link.from_node.name, link.from_socket.identifier))
            stack.append(link.from_node)
    while stack:
        node = stack.pop()
        if node.name in seen:
            continue
        seen.add(node.name)
        entry = [node.bl_idname, node.name, node.mute, _node_settings(node)]
        for inp in node.inputs:
            live = [l for l in inp.links if l.is_valid and not l.is_muted]
            if live:
                entry.append((inp.identifier, "link", live[0].from_node.name, live[0].from_socket.identifier))
                stack.append(live[0].from_node)
            elif hasattr(inp, "default_value"):
                entry.append((inp.identifier, _value(inp.default_value)))
        parts.append(tuple(entry))
    return hashlib.sha1(repr(sorted(map(repr, parts))).encode()).hexdigest()[:16]


def _records(material) -> dict:
    material = getattr(material, "original", None) or material
    records = material.get(PROPERTY)
    return records if records is not None else {}


def lookup(material, node, input_name: str):
    """(image, None) when the input has an up-to-date baked image; (None, why) when it had one;
    (None, None) when it was never baked."""
    if material is None:
        return None, None
    entry = _records(material).get(key(node, input_name))
    if entry is None:
        return None, None
    image = bpy.data.images.get(entry.get("image", ""))
    if image is None:
        return None, f"its baked image '{entry.get('image')}' is missing"
    if entry.get("signature") != signature(node.inputs[input_name]):
        return None, "changed since it was baked"
    return image, None


def record(material, node, input_name: str, image, obj) -> None:
    stored = material.get(PROPERTY)
    records = stored.to_dict() if stored is not None else {}
    records[key(node, input_name)] = {"image": image.name, "signature": signature(node.inputs[input_name]),
                                      "object": obj.name}
    material[PROPERTY] = records
