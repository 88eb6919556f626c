"""Lamina scene dict → a Cycles job: the parent's half of the converter (no bpy here).

Geometry is taken from Lamina's own loader (``load_scene_data``): the world-space triangles and
per-corner shading normals Lamina traces, one array set per object. Built-in shapes, inline meshes
and transforms therefore reach Cycles as exactly the same triangles and normals, with nothing
re-tessellated. Everything else (camera, film, lights, materials, world, render settings) is copied
from the dict itself; ``to_cycles.py`` (run in the bpy child) turns the job into a Blender scene.

Materials reach Cycles in one of two ways: converted from the Lamina material (diffuse,
conductor, dielectric, the coat over a diffuse body), or, for the names a scene gives Principled
BSDF settings (``prepare``'s ``principled``), as a Principled BSDF node with those settings, the
Lamina material being whatever the scene says (the add-on's export of the same settings, a
preset, ...). ``principled_inputs`` translates the settings to the node's input names here, so the
child only sets sockets.

A feature the converter does not support raises :class:`Unsupported` naming it: a benchmark
scene that used one would otherwise be compared with a scene Cycles never saw.
"""
from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np

SUPPORTED_MATERIALS = ("diffuse", "conductor", "dielectric", "layered")
SUPPORTED_LIGHTS = ("area", "point", "sun")

#: Principled settings (the keys of addon/export/principled.py's ``principled_material``) → the
#: Principled BSDF node's inputs. ``emission`` is left out on purpose: no benchmark scene has an
#: emitting surface (see ``check_material``).
PRINCIPLED_INPUTS = {
    "base_color": "Base Color", "metallic": "Metallic", "roughness": "Roughness", "ior": "IOR",
    "specular_ior_level": "Specular IOR Level", "specular_tint": "Specular Tint",
    "transmission": "Transmission Weight", "coat_weight": "Coat Weight", "coat_roughness": "Coat Roughness",
    "coat_ior": "Coat IOR", "coat_tint": "Coat Tint", "sheen_weight": "Sheen Weight",
    "sheen_roughness": "Sheen Roughness", "sheen_tint": "Sheen Tint",
}
_PRINCIPLED_COLOURS = ("base_color", "specular_tint", "coat_tint", "sheen_tint")


class Unsupported(ValueError):
    pass


def _check_microfacet(name: str, m: dict) -> None:
    # Cycles' Metallic/Glass nodes are set to plain GGX (to_cycles.py), whose shadowing is the
    # height-correlated Smith term: only Lamina's default model has a Cycles twin.
    if m.get("distribution", "ggx") != "ggx" or m.get("masking", "height-correlated") != "height-correlated":
        raise Unsupported(f"material {name}: only GGX with height-correlated masking has a Cycles counterpart")
    if "roughness_v" in m:
        raise Unsupported(f"material {name}: anisotropic roughness is not converted")


def check_material(name: str, m) -> None:
    if not isinstance(m, dict) or m.get("type") not in SUPPORTED_MATERIALS:
        raise Unsupported(f"material {name}: type {m.get('type') if isinstance(m, dict) else m!r} is not converted")
    kind = m["type"]
    if "emission" in m:
        raise Unsupported(f"material {name}: emission is not converted (mesh lights are two-sided in both "
                          "renderers, but no benchmark scene needs them)")
    if kind == "conductor":
        if "metal" in m or "eta" not in m or "k" not in m:
            raise Unsupported(f"material {name}: give the conductor's eta and k explicitly")
        if m.get("tint", 1) != 1 or m.get("eta_above", 1.0) != 1.0:
            raise Unsupported(f"material {name}: tint / eta_above are not converted")
        _check_microfacet(name, m)
    elif kind == "dielectric":
        if m.get("ior_above", 1.0) != 1.0:
            raise Unsupported(f"material {name}: ior_above is not converted")
        _check_microfacet(name, m)
    elif kind == "layered":
        coat_over_body(name, m)
    for key, value in m.items():
        if isinstance(value, dict) and "texture" in value:
            raise Unsupported(f"material {name}: textures are not converted ({key})")


def coat_over_body(name: str, m: dict) -> tuple[dict, dict]:
    """The one layered form with a Cycles counterpart (Principled BSDF with Coat): a dielectric
    coat over a diffuse body with an empty slab between them. Returns (coat, body)."""
    ifs, media = m.get("interfaces", []), m.get("media", [])
    ok = (len(ifs) == 2 and ifs[0].get("type") == "dielectric" and ifs[1].get("type") == "diffuse"
          and len(media) == 1 and float(media[0].get("sigma_t", 1)) == 0.0)
    if not ok:
        raise Unsupported(f"material {name}: only a dielectric coat over a diffuse body (empty slab) "
                          "is converted (to Principled BSDF with Coat)")
    _check_microfacet(name, ifs[0])
    return ifs[0], ifs[1]


def principled_inputs(name: str, p: dict) -> dict:
    """Principled settings ``p`` → {node input name: value} (colours as 3 floats). Unknown keys,
    colours that are not 3 numbers and a distribution other than GGX are refused: a typo would
    otherwise leave Blender's default in Cycles while Lamina's export read the intended value."""
    out = {}
    for key, value in p.items():
        if key == "distribution":
            if str(value).lower() != "ggx":
                raise Unsupported(f"material {name}: Principled distribution {value!r}: only plain GGX is "
                                  "compared (Lamina is single-scattering)")
            continue
        if key not in PRINCIPLED_INPUTS:
            raise Unsupported(f"material {name}: Principled setting {key!r} is not converted "
                              f"(known: {', '.join(PRINCIPLED_INPUTS)})")
        if key in _PRINCIPLED_COLOURS:
            if isinstance(value, (int, float)) or len(value) != 3:
                raise Unsupported(f"material {name}: Principled {key} must be 3 numbers (linear RGB)")
            out[PRINCIPLED_INPUTS[key]] = [float(x) for x in value]
        else:
            out[PRINCIPLED_INPUTS[key]] = float(value)
    return out


def check_light(i: int, light: dict) -> None:
    if light.get("type") not in SUPPORTED_LIGHTS:
        raise Unsupported(f"lights[{i}]: type {light.get('type')} is not converted")
    if "cutoff_angle" in light or "beam_width" in light:
        raise Unsupported(f"lights[{i}]: Lamina's cutoff/beam directional light has no Cycles counterpart "
                          "(use spread)")


def cycles_filter(filt: dict) -> tuple[str, float]:
    """Lamina ``film.filter`` → (Cycles filter type, ``filter_width``): the same type and width,
    which mean the same filter in both (backend/film.py follows Cycles' ``filter_table``)."""
    kind = filt.get("type", "blackman-harris")
    width = float(filt.get("width", 1.0 if kind == "box" else 1.5))
    return {"box": "BOX", "blackman-harris": "BLACKMAN_HARRIS", "gaussian": "GAUSSIAN"}[kind], width


def prepare(data: dict, job_dir: Path, cycles_overrides: dict | None = None,
            principled: dict | None = None) -> Path:
    """Write ``job.json`` + ``geometry.npz`` for the bpy child into ``job_dir``; returns the json path.
    ``cycles_overrides`` (deliberate mistakes, for ``sensitivity.py`` only) is passed through.
    ``principled`` (material name → Principled settings, ``PeerScene.principled``): Cycles renders
    those materials as a Principled BSDF with the settings instead of converting Lamina's."""
    from backend.scene.loader import load_scene_data

    principled = dict(principled or {})
    materials = data.get("materials", {})
    missing = sorted(set(principled) - set(materials))
    if missing:
        # A name that matches no material would leave the material it was meant for converted.
        raise Unsupported(f"Principled settings for unknown material(s) {', '.join(missing)}")
    job_principled = {name: principled_inputs(name, p) for name, p in principled.items()}
    for name, m in materials.items():
        if name not in principled:
            check_material(name, m)
    for i, light in enumerate(data.get("lights", [])):
        check_light(i, light)
    world = data.get("world", {"type": "none"})
    if world.get("type", "none") not in ("constant", "none"):
        raise Unsupported(f"world type {world.get('type')} is not converted")
    cycles_filter_ = cycles_filter(data["film"].get("filter", {}))
    if data["camera"].get("type") != "perspective" or "dof" in data["camera"]:
        raise Unsupported("only a perspective pinhole camera is converted")

    scene = load_scene_data(copy.deepcopy(data), "<peers>")
    soup = scene.soup
    arrays, objects = {}, []
    for oi, obj in enumerate(data.get("objects", [])):
        tri = np.flatnonzero(soup.object_id == oi)
        if tri.size == 0:
            continue
        mats = soup.material[tri]
        slot_names = [scene.material_names[i] for i in np.unique(mats)]
        slot_of = {scene.material_names[i]: s for s, i in enumerate(np.unique(mats))}
        arrays[f"o{oi}_pos"] = soup.vertices[tri].astype(np.float32)
        if soup.normals is not None:
            arrays[f"o{oi}_nrm"] = soup.normals[tri].astype(np.float32)
        arrays[f"o{oi}_slot"] = np.array([slot_of[scene.material_names[i]] for i in mats], np.int32)
        objects.append({"index": oi, "name": obj.get("name", f"object {oi}"), "materials": slot_names,
                        "visible_camera": obj.get("visible_camera", True)})
    job = {"film": data["film"], "cycles_filter": cycles_filter_, "camera": data["camera"], "render": data.get("render", {}),
           "materials": {k: v for k, v in materials.items() if k not in principled},
           "principled": job_principled, "lights": data.get("lights", []), "world": world,
           "objects": objects}
    if cycles_overrides:
        job["cycles_overrides"] = dict(cycles_overrides)
    job_dir.mkdir(parents=True, exist_ok=True)
    np.savez(job_dir / "geometry.npz", **arrays)
    path = job_dir / "job.json"
    path.write_text(json.dumps(job, indent=1), encoding="utf-8")
    return path
