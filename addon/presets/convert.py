"""Preset material JSON (docs/materials.md) → a material's layer-stack properties.

Every field of the JSON is either represented in the stack properties or listed in the returned
``dropped`` list ("field path: why") — never silently lost. The operator keeps the preset's JSON
with the material (export/preset_link.py), so an unedited preset still renders exactly; the list
tells the user what an edit would lose. Values outside the editor's ranges (a colour above 1, a
microflake spread above 1) are clamped by Blender's properties: such clamps are reported too.
"""
from __future__ import annotations

import math
from pathlib import Path

import bpy

from ...backend.layered.phase_schema import BY_NAME, default_of
from ..ops.stack import add_layer, default_name
from .library import PresetError, find, read_document

TEXTURE_KEYS = ("texture", "scale", "colorspace", "channel")
LAYERED_OPTIONS = ("estimator", "pdf", "pdf_constant", "max_vertices")
REL_TOLERANCE = 2e-6         # float32 properties: values round-trip to ~6e-8 relative


def _close(a, b) -> bool:
    if isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    return abs(float(a) - float(b)) <= REL_TOLERANCE * max(1.0, abs(float(b)))


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_rgb(v) -> bool:
    return isinstance(v, list) and len(v) == 3 and all(_is_number(x) for x in v)


class Converter:
    def __init__(self, base_dir: Path, name: str):
        self.base_dir = Path(base_dir)
        self.name = name
        self.dropped: list[str] = []
        self.nested: list = []           # materials created for nested stacks

    # ------------------------------------------------------------------ helpers

    def drop(self, path: str, why: str) -> None:
        self.dropped.append(f"{path}: {why}")

    def unknown(self, d: dict, used: set, path: str) -> None:
        for key in d:
            if key not in used and not key.startswith("_"):
                self.drop(f"{path}.{key}" if path else key, "not editable in the stack editor")

    def put(self, owner, prop: str, value, path: str) -> None:
        """Set a property and report if Blender clamped it to the editor's range."""
        setattr(owner, prop, value)
        got = getattr(owner, prop)
        got = list(got) if isinstance(value, (list, tuple)) else got
        if not _close(got, value):
            shown = [round(x, 4) for x in got] if isinstance(got, list) else round(got, 4)
            self.drop(path, f"{value} clamped to {shown} (the editor's range)")

    def image(self, tex: dict, path: str, colour: bool):
        """A Blender image for a texture reference; unsupported texture options are reported."""
        file = tex.get("texture")
        if not isinstance(file, str) or not file:
            raise PresetError(f"{self.name}: {path}.texture: expected a file name")
        p = Path(file)
        if not p.is_absolute():
            p = self.base_dir / p
        try:
            img = bpy.data.images.load(str(p), check_existing=True)
        except RuntimeError as exc:
            raise PresetError(f"{self.name}: {path}: cannot load texture {p}: {exc}") from None
        cs = tex.get("colorspace", "auto")
        # Scalar parameters read "auto" images as stored, like the backend (docs/materials.md).
        if cs == "linear" or (cs == "auto" and not colour):
            img.colorspace_settings.name = "Non-Color"
        elif cs == "sRGB":
            img.colorspace_settings.name = "sRGB"
        if tex.get("channel", -1) != -1:
            self.drop(f"{path}.channel", "a single image channel (the editor reads luminance)")
        for key in tex:
            if key not in TEXTURE_KEYS and not key.startswith("_"):
                self.drop(f"{path}.{key}", "not editable in the stack editor")
        return img

    def scalar(self, owner, prop: str, tex_prop: str | None, value, path: str, default: float) -> None:
        if value is None:
            value = default
        if isinstance(value, dict) and tex_prop is not None:
            scale = value.get("scale", 1.0)
            if not _is_number(scale):
                self.drop(f"{path}.scale", "a non-scalar scale")
                scale = 1.0
            self.put(owner, prop, float(scale), f"{path}.scale")
            setattr(owner, tex_prop, self.image(value, path, colour=False))
        elif _is_number(value):
            self.put(owner, prop, float(value), path)
            if tex_prop is not None:
                setattr(owner, tex_prop, None)
        else:
            self.drop(path, "a texture here is not editable" if isinstance(value, dict) else f"unexpected value {value!r}")
            setattr(owner, prop, float(default))

    def colour(self, owner, prop: str, tex_prop: str | None, value, path: str, default) -> None:
        if value is None:
            value = default
        if isinstance(value, dict) and tex_prop is not None:
            scale = value.get("scale", 1.0)
            scale = [float(scale)] * 3 if _is_number(scale) else scale
            if not _is_rgb(scale):
                self.drop(f"{path}.scale", f"unexpected scale {scale!r}")
                scale = [1.0, 1.0, 1.0]
            self.put(owner, prop, [float(x) for x in scale], f"{path}.scale")
            setattr(owner, tex_prop, self.image(value, path, colour=True))
            return
        if _is_number(value):
            value = [float(value)] * 3
        if _is_rgb(value):
            self.put(owner, prop, [float(x) for x in value], path)
            if tex_prop is not None:
                setattr(owner, tex_prop, None)
        else:
            self.drop(path, "a texture here is not editable" if isinstance(value, dict) else f"unexpected value {value!r}")

    # ------------------------------------------------------------------ interfaces

    def roughness(self, layer, itf: dict, path: str, default: float) -> None:
        a = itf.get("roughness", default)
        layer.roughness_texture = None
        layer.roughness_texture_alpha = False
        if isinstance(a, dict):            # a file's roughness texture holds α: exported unsquared
            scale = a.get("scale", 1.0)
            if not _is_number(scale):
                self.drop(f"{path}.roughness.scale", "a non-scalar scale")
                scale = 1.0
            self.put(layer, "roughness", math.sqrt(max(float(scale), 0.0)), f"{path}.roughness.scale")
            layer.roughness_texture = self.image(a, f"{path}.roughness", colour=False)
            layer.roughness_texture_alpha = True
        elif _is_number(a):
            self.put(layer, "roughness", math.sqrt(max(float(a), 0.0)), f"{path}.roughness")
        else:
            raise PresetError(f"{self.name}: {path}.roughness: unexpected value {a!r}")
        if "roughness_v" in itf:
            av = itf["roughness_v"]
            if _is_number(av):
                layer.use_anisotropy = True
                self.put(layer, "roughness_v", math.sqrt(max(float(av), 0.0)), f"{path}.roughness_v")
            else:
                self.drop(f"{path}.roughness_v", "a texture here is not editable")
        dist = itf.get("distribution", "ggx")
        if dist in ("ggx", "beckmann"):
            layer.distribution = dist.upper()
        else:
            self.drop(f"{path}.distribution", f"unknown {dist!r}")
        masking = itf.get("masking", "height-correlated")
        if masking in ("height-correlated", "separable"):
            layer.masking = masking.upper().replace("-", "_")
        else:
            self.drop(f"{path}.masking", f"unknown {masking!r}")

    def interface(self, layer, itf, path: str) -> None:
        if isinstance(itf, str):                 # a preset name used as an interface
            found = find(itf)
            if found is None:
                raise PresetError(f"{self.name}: {path}: unknown preset {itf!r}")
            _, label, doc = read_document(found)
            self.nested_material(layer, doc, path, label, Path(found).parent)
            return
        if not isinstance(itf, dict):
            raise PresetError(f"{self.name}: {path}: expected an interface object")
        kind = itf.get("type")
        used = {"type", "roughness", "roughness_v", "distribution", "masking"}
        if kind == "dielectric":
            layer.kind = "DIELECTRIC"
            used.add("ior")
            self.scalar(layer, "ior", None, itf.get("ior", 1.5), f"{path}.ior", 1.5)
            self.roughness(layer, itf, path, 0.0)
            tc = itf.get("transmission_color")
            if tc is not None:
                used.add("transmission_color")
                if tc not in (1, 1.0, [1, 1, 1], [1.0, 1.0, 1.0]):
                    self.drop(f"{path}.transmission_color", "not editable in the stack editor")
        elif kind == "conductor":
            layer.kind = "CONDUCTOR"
            used |= {"metal", "eta", "k", "tint"}
            if "eta" in itf or "k" in itf:
                layer.metal = "CUSTOM"
                self.colour(layer, "eta", None, itf.get("eta"), f"{path}.eta", [1.0, 1.0, 1.0])
                self.colour(layer, "k", None, itf.get("k"), f"{path}.k", [0.0, 0.0, 0.0])
            else:
                metal = itf.get("metal", "Cu")
                try:
                    layer.metal = metal
                except TypeError:
                    raise PresetError(f"{self.name}: {path}.metal: unknown metal {metal!r}") from None
            self.colour(layer, "tint", None, itf.get("tint", 1.0), f"{path}.tint", [1.0, 1.0, 1.0])
            self.roughness(layer, itf, path, 0.1)
        elif kind == "diffuse":
            layer.kind = "DIFFUSE"
            used = {"type", "color"}
            self.colour(layer, "color", "color_texture", itf.get("color"), f"{path}.color", [0.8, 0.8, 0.8])
        elif kind == "null":
            layer.kind = "NULL"
            used = {"type"}
        elif kind == "layered":
            used = set(itf)                      # the nested converter reports its own fields
            self.nested_material(layer, itf, path, f"{self.name} {path}", self.base_dir)
        else:
            raise PresetError(f"{self.name}: {path}: interface type {kind!r} cannot be edited as a stack")
        if kind != "layered":
            used |= self.detail(layer, itf, path)
        self.unknown(itf, used, path)

    def detail(self, layer, itf: dict, path: str) -> set:
        """The interface's normal map and bump map (a texture each; a constant normal or height is
        not editable here and is reported). Returns the keys read."""
        layer.normal_texture = None
        layer.normal_strength = 1.0
        layer.bump_texture = None
        layer.bump_distance, layer.bump_strength, layer.bump_invert = 1.0, 1.0, False
        normal = itf.get("normal")
        if isinstance(normal, dict):
            if normal.get("scale", 1.0) not in (1, 1.0, [1, 1, 1], [1.0, 1.0, 1.0]):
                self.drop(f"{path}.normal.scale", "a scaled normal map")
            layer.normal_texture = self.image(normal, f"{path}.normal", colour=False)
            self.scalar(layer, "normal_strength", None, itf.get("normal_strength", 1.0),
                        f"{path}.normal_strength", 1.0)
        elif normal is not None:
            self.drop(f"{path}.normal", "a constant normal (the editor takes a normal-map image)")
        bump = itf.get("bump")
        if isinstance(bump, dict) and isinstance(bump.get("height"), dict):
            height = bump["height"]
            if height.get("scale", 1.0) not in (1, 1.0):
                self.drop(f"{path}.bump.height.scale", "a scaled height (fold it into the distance)")
            layer.bump_texture = self.image(height, f"{path}.bump.height", colour=False)
            self.scalar(layer, "bump_distance", None, bump.get("distance", 1.0), f"{path}.bump.distance", 1.0)
            self.scalar(layer, "bump_strength", None, bump.get("strength", 1.0), f"{path}.bump.strength", 1.0)
            layer.bump_invert = bool(bump.get("invert", False))
            self.unknown(bump, {"height", "distance", "strength", "invert"}, f"{path}.bump")
        elif bump is not None:
            self.drop(f"{path}.bump", "a constant height tilts nothing")
        return {"normal", "normal_strength", "bump"}

    def nested_material(self, layer, doc: dict, path: str, label: str, base_dir: Path) -> None:
        nested = bpy.data.materials.new(f"{label} (nested)")
        self.nested.append(nested)
        sub = Converter(base_dir, self.name)
        sub.fill(nested, doc)
        self.dropped += [f"{path}.{d}" for d in sub.dropped]
        self.nested += sub.nested
        layer.kind = "MATERIAL"
        layer.material = nested

    # ------------------------------------------------------------------ media

    def medium(self, layer, med, path: str) -> None:
        if not isinstance(med, dict):
            raise PresetError(f"{self.name}: {path}: expected a medium object")
        self.scalar(layer, "thickness", "thickness_texture", med.get("thickness"), f"{path}.thickness", 1.0)
        sigma = med.get("sigma_t", 1.0)              # the schema's default is 1, not 0
        rgb_sigma = _is_rgb(sigma) or (isinstance(sigma, dict) and _is_rgb(sigma.get("scale")))
        layer.use_chromatic = rgb_sigma
        if rgb_sigma:
            self.colour(layer, "sigma_t_rgb", "sigma_t_texture", sigma, f"{path}.sigma_t", [1.0, 1.0, 1.0])
        else:
            self.scalar(layer, "sigma_t", "sigma_t_texture", sigma, f"{path}.sigma_t", 1.0)
        self.colour(layer, "albedo", "albedo_texture", med.get("albedo", 1.0), f"{path}.albedo", [1.0, 1.0, 1.0])
        self.phase(layer, med.get("phase") or {"type": "isotropic"}, f"{path}.phase")
        self.unknown(med, {"thickness", "sigma_t", "albedo", "phase"}, path)

    def phase(self, layer, phase, path: str) -> None:
        if not isinstance(phase, dict):
            raise PresetError(f"{self.name}: {path}: expected a phase-function object")
        name = phase.get("type", "isotropic")
        kind = BY_NAME.get(name)
        if kind is None or (name == "sggx" and "matrix" in phase):
            layer.phase = "ISOTROPIC"
            what = "an explicit SGGX matrix" if name == "sggx" else f"phase function {name!r}"
            self.drop(path, f"{what} (the editor shows it as isotropic)")
            self.unknown(phase, set(phase), path)
            return
        layer.phase = kind.enum
        used, choices = {"type"}, {}
        for p in kind.params:                       # its row in backend/layered/phase_schema.py
            used.add(p.key)
            where = f"{path}.{p.key}"
            if p.kind == "choice":
                value = phase.get(p.key, p.default)
                value = value if value in [c[0] for c in p.choices] else p.default
                choices[p.key] = value
                setattr(layer, p.prop, value.upper())
            elif p.kind == "axis":
                default = list(default_of(p, choices))
                self.axis(layer, p, phase.get(p.key, default), where, default)
            else:
                default = p.default if p.ui_default is None else p.ui_default
                self.scalar(layer, p.prop, None, phase.get(p.key, default), where, default)
        self.unknown(phase, used, path)

    def axis(self, layer, param, value, path: str, default) -> None:
        setattr(layer, param.texture_prop, None)
        if isinstance(value, dict):               # a normal-map-encoded axis texture
            if value.get("scale", 1.0) not in (1, 1.0, [1, 1, 1], [1.0, 1.0, 1.0]):
                self.drop(f"{path}.scale", "a scaled axis texture")
            setattr(layer, param.prop, default)
            setattr(layer, param.texture_prop, self.image(value, path, colour=False))
            return
        self.colour(layer, param.prop, None, value, path, default)

    # ------------------------------------------------------------------ whole material

    def fill(self, mat, doc: dict) -> None:
        if not isinstance(doc, dict):
            raise PresetError(f"{self.name}: expected a material object")
        kind = doc.get("type")
        if kind == "emission":
            raise PresetError(f"{self.name}: an emission material is not a layer stack")
        layered = kind == "layered"
        interfaces = doc.get("interfaces") if layered else [doc]
        media = (doc.get("media") or []) if layered else []
        if not isinstance(interfaces, list) or not interfaces:
            raise PresetError(f"{self.name}: the stack has no interfaces")
        if not isinstance(media, list) or len(media) != len(interfaces) - 1:
            raise PresetError(f"{self.name}: {len(interfaces)} interfaces need {len(interfaces) - 1} media")
        settings = mat.lamina
        settings.layers.clear()
        for i, itf in enumerate(interfaces):
            layer = add_layer(settings, "DIELECTRIC", i)
            path = f"interfaces[{i}]" if layered else ""
            if layered:
                self.interface(layer, itf, path)
            else:
                self.interface(layer, {k: v for k, v in itf.items() if k != "emission"}, "")
            layer.name = ""
            custom = itf.get("_name") if isinstance(itf, dict) else None
            layer.name = custom if isinstance(custom, str) and custom else default_name(settings, layer.kind)
            if i < len(media):
                self.medium(layer, media[i], f"media[{i}]")
        self.dropped = [d[1:] if d.startswith(".") else d for d in self.dropped]
        if layered:
            self.unknown(doc, {"type", "interfaces", "media", "emission"}, "")
        self.emission(settings, doc.get("emission"))
        settings.active_layer = 0
        settings.use_stack = True

    def emission(self, settings, value) -> None:
        settings.emission_strength = 0.0
        settings.emission_color = (1.0, 1.0, 1.0)
        if value is None or value == 0:
            return
        if _is_number(value):
            value = [float(value)] * 3
        if not _is_rgb(value):
            self.drop("emission", "a texture here is not editable")
            return
        peak = max(float(v) for v in value)
        if peak <= 0:
            return
        self.put(settings, "emission_strength", peak, "emission")
        self.put(settings, "emission_color", [float(v) / peak for v in value], "emission")


def material_from_json(mat, doc: dict, base_dir: Path, name: str = "") -> list[str]:
    """Replace ``mat``'s stack with the material ``doc``; returns the fields not represented."""
    conv = Converter(base_dir, name or mat.name)
    conv.fill(mat, doc)
    return [d.lstrip(".") for d in conv.dropped]
