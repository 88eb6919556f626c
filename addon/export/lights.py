"""Blender lights → scene-file lights, in Blender's own units (Cycles ≥ 4.0 conventions).

Only raw Blender quantities are written (power in W, sun strength in W/m², sizes in local units
with the transform carrying the scale); the radiometric conversions live in the backend.
Colour = light colour × temperature colour (if used) × 2^exposure.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import bpy

from ..util import degrees, matrix_rows, rgb


def light_colour(light) -> list[float]:
    c = rgb(light.color)
    if getattr(light, "use_temperature", False):
        t = rgb(light.temperature_color)
        c = [a * b for a, b in zip(c, t)]
    scale = 2.0 ** float(getattr(light, "exposure", 0.0))
    return [x * scale for x in c]


def _light_node_tree(light):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        use = getattr(light, "use_nodes", False)
    return light.node_tree if use and light.node_tree is not None else None


def ies_json(light, notes: list[str]):
    """``{"file": ...}`` / ``{"data": ...}`` from Lamina's setting or a Cycles IES Texture node."""
    found = ies_source(light, notes)
    return found[0] if found else None


def ies_source(light, notes: list[str]):
    """(ies entry, strength multiplier) or None. The IES Texture node's Strength input is a
    plain multiplier of the light's power (docs/lights.md)."""
    settings = light.lamina
    if settings.ies_mode == "FILE" and settings.ies_file:
        return {"file": str(Path(bpy.path.abspath(settings.ies_file, library=light.library)))}, 1.0
    if settings.ies_mode == "TEXT" and settings.ies_text is not None:
        return {"data": settings.ies_text.as_string()}, 1.0
    if settings.ies_mode != "NONE":
        notes.append(f"light '{light.name}': IES profile selected but not set (ignored)")
        return None
    tree = _light_node_tree(light)
    if tree is None:
        return None
    nodes = [n for n in tree.nodes if n.bl_idname == "ShaderNodeTexIES" and not n.mute]
    if not nodes:
        return None
    if len(nodes) > 1:
        notes.append(f"light '{light.name}': several IES Texture nodes (the first is used)")
    node = nodes[0]
    strength_socket = node.inputs.get("Strength")
    strength = float(strength_socket.default_value) if strength_socket is not None else 1.0
    if strength_socket is not None and strength_socket.is_linked:
        notes.append(f"light '{light.name}': {node.name}.Strength input (value used)")
    # "_node": the backend ignores it; the add-on's messages name the node (export/names.py).
    if node.mode == "INTERNAL":
        if node.ies is None:
            return None
        return {"data": node.ies.as_string(), "_node": node.name}, strength
    if node.filepath:
        return {"file": str(Path(bpy.path.abspath(node.filepath, library=light.library))),
                "_node": node.name}, strength
    return None


# Cycles' candela → W/sr conversion (lm/W), the same number as backend/ies/profile.py's
# LUMINOUS_EFFICACY (a test checks): I [W/sr] = power [W] × cd / 177.83 (docs/lights.md, IES lights).
LUMINOUS_EFFICACY = 177.83
_PEAK_CACHE: dict = {}


def ies_peak_candela(entry: dict) -> float:
    """The largest candela value of an IES profile (``{"file": ...}`` or ``{"data": ...}``), with
    the file's candela multiplier and ballast factors applied, read by the backend's LM-63 reader
    (bpy-free, NumPy only). Raises the reader's error for a malformed file."""
    from ...backend.ies.lm63 import parse_lm63, read_lm63, to_cycles_frame
    if "file" in entry:
        path = Path(entry["file"])
        key = ("file", str(path), path.stat().st_mtime_ns if path.is_file() else None)
    else:
        key = ("data", hash(entry["data"]))
    if key not in _PEAK_CACHE:
        parsed = read_lm63(entry["file"]) if "file" in entry else parse_lm63(entry["data"], "IES text")
        _PEAK_CACHE[key] = float(to_cycles_frame(parsed)[2].max())
        if len(_PEAK_CACHE) > 64:
            _PEAK_CACHE.pop(next(iter(_PEAK_CACHE)))
    return _PEAK_CACHE[key]


def ies_peak(light) -> dict | None:
    """What the IES panel shows: the profile's peak in candela and the light's resulting peak
    radiant intensity in W/sr (Cycles' units: power × IES-node strength × 2^exposure × cd / 177.83;
    the light colour multiplies that per channel). None without a profile; ``{"error": ...}`` for
    a file the reader rejects."""
    found = ies_source(light, [])
    if found is None:
        return None
    entry, strength = found
    try:
        cd = ies_peak_candela(entry)
    except Exception as exc:  # noqa: BLE001 - shown in the panel, the render reports it too
        return {"error": str(exc)}
    watts = float(light.energy) * strength * 2.0 ** float(getattr(light, "exposure", 0.0))
    return {"candela": cd, "watts": watts, "w_per_sr": watts * cd / LUMINOUS_EFFICACY}


def light_json(obj, matrix_world, notes: list[str]) -> dict | None:
    light = obj.data
    kind = light.type
    out = {"type": kind.lower(), "_name": obj.name, "to_world": matrix_rows(matrix_world),
           "color": light_colour(light)}
    if kind in ("POINT", "SPOT"):
        out["power"] = float(light.energy)
        out["radius"] = float(light.shadow_soft_size)
        out["soft_falloff"] = bool(getattr(light, "use_soft_falloff", False))
        if kind == "SPOT":
            out["spot_size"] = min(max(degrees(light.spot_size), 1.0), 180.0)
            out["spot_blend"] = float(light.spot_blend)
        found = ies_source(light, notes)
        if found is not None:
            out["ies"], strength = found
            out["power"] *= strength
    elif kind == "SUN":
        out["strength"] = float(light.energy)
        out["angle"] = min(degrees(light.angle), 180.0)
    elif kind == "AREA":
        out["shape"] = light.shape.lower()
        out["size"] = float(light.size)
        out["size_y"] = float(light.size_y)
        out["power"] = float(light.energy)
        out["normalize"] = bool(getattr(light, "normalize", True))
        settings = light.lamina
        if settings.beam_mode == "CONE":
            cutoff = min(degrees(settings.cutoff_angle), 90.0)
            out["cutoff_angle"] = cutoff
            out["beam_width"] = min(degrees(settings.beam_width), cutoff)
        else:
            # float32 π is a hair above 180°: clamp to the documented range.
            out["spread"] = min(degrees(getattr(light, "spread", 3.141592653589793)), 180.0)
    else:
        notes.append(f"light '{light.name}': type {kind} is not supported (skipped)")
        return None
    if getattr(obj, "visible_camera", False) and kind in ("AREA", "POINT", "SPOT") and \
            (kind == "AREA" or light.shadow_soft_size > 0):
        out["visible_camera"] = True
    return out
