"""Material presets: JSON files in the shared material schema (docs/materials.md) ↔ layer stacks.

The menu lists ``*.json`` presets from the extension's ``presets/`` folder and the user's preset
folder; other code (the preset library) can add entries by appending a ``draw(menu, context)``
function to ``MENU_HOOKS``. A preset file is ``{"name", "category", "description", "tags",
"material": {...}}`` (backend/presets.py), or a bare material object.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import bpy
from bpy.props import StringProperty

from .. import preferences
from ..export.images import ImageExporter, safe_name
from ..export.stack import StackError, stack_json
from .stack import add_layer, default_name

SHIPPED = Path(__file__).resolve().parent.parent.parent / "presets"
MENU_HOOKS: list = []          # draw(menu, context) functions added by the preset library


class PresetError(Exception):
    pass


def user_preset_dir(create: bool = False) -> Path | None:
    try:
        return Path(bpy.utils.extension_path_user(preferences.ADDON_ID, path="presets", create=create))
    except (ValueError, RuntimeError, TypeError):       # development: not an installed extension
        return None


def preset_files() -> list[Path]:
    found, seen = [], set()
    for folder in (user_preset_dir(), SHIPPED):
        if folder is None or not folder.is_dir():
            continue
        for path in sorted(folder.rglob("*.json")):
            if path.stem not in seen:
                seen.add(path.stem)
                found.append(path)
    return found


def read_preset(path: Path) -> tuple[str, dict]:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PresetError(f"{path.name}: cannot read preset ({exc})") from None
    material = doc.get("material", doc) if isinstance(doc, dict) else None
    if not isinstance(material, dict) or "type" not in material:
        raise PresetError(f"{path.name}: no material in the preset")
    return str(doc.get("name", path.stem)), material


# ------------------------------------------------------------------------ JSON → stack

def _number(value, base_dir: Path, what: str):
    """(constant, image) from a texturable scalar."""
    if isinstance(value, dict):
        image = _load_image(value.get("texture"), base_dir)
        scale = value.get("scale", 1.0)
        return float(scale if not isinstance(scale, list) else scale[0]), image
    return float(value), None


def _colour(value, base_dir: Path, default):
    if isinstance(value, dict):
        image = _load_image(value.get("texture"), base_dir)
        scale = value.get("scale", 1.0)
        return (list(scale) if isinstance(scale, list) else [float(scale)] * 3), image
    if value is None:
        return list(default), None
    if isinstance(value, (int, float)):
        return [float(value)] * 3, None
    return [float(v) for v in value[:3]], None


def _load_image(path, base_dir: Path):
    if not path:
        return None
    p = Path(path)
    if not p.is_absolute():
        p = base_dir / p
    try:
        return bpy.data.images.load(str(p), check_existing=True)
    except RuntimeError as exc:
        raise PresetError(f"cannot load texture {p}: {exc}") from None


def _set_roughness(layer, itf: dict, base_dir: Path) -> None:
    alpha, image = _number(itf.get("roughness", 0.1 if itf.get("type") == "conductor" else 0.0),
                           base_dir, "roughness")
    layer.roughness = math.sqrt(max(alpha, 0.0))
    layer.roughness_texture = image
    if "roughness_v" in itf:
        alpha_v, _ = _number(itf["roughness_v"], base_dir, "roughness_v")
        layer.use_anisotropy = True
        layer.roughness_v = math.sqrt(max(alpha_v, 0.0))
    layer.distribution = "BECKMANN" if itf.get("distribution") == "beckmann" else "GGX"


def _fill_interface(layer, itf, base_dir: Path, name: str) -> None:
    if isinstance(itf, str):
        raise PresetError(f"{name}: preset names inside stacks are not supported in the editor")
    kind = itf.get("type")
    if kind == "dielectric":
        layer.kind = "DIELECTRIC"
        layer.ior = float(itf.get("ior", 1.5))
        _set_roughness(layer, itf, base_dir)
    elif kind == "conductor":
        layer.kind = "CONDUCTOR"
        if "eta" in itf or "k" in itf:
            layer.metal = "CUSTOM"
            layer.eta = _colour(itf.get("eta"), base_dir, (1.0, 1.0, 1.0))[0]
            layer.k = _colour(itf.get("k"), base_dir, (0.0, 0.0, 0.0))[0]
        else:
            layer.metal = itf.get("metal", "Cu")
        if "tint" in itf:
            layer.tint = _colour(itf["tint"], base_dir, (1.0, 1.0, 1.0))[0]
        _set_roughness(layer, itf, base_dir)
    elif kind == "diffuse":
        layer.kind = "DIFFUSE"
        layer.color, layer.color_texture = _colour(itf.get("color"), base_dir, (0.8, 0.8, 0.8))
    elif kind == "null":
        layer.kind = "NULL"
    elif kind == "layered":
        nested = bpy.data.materials.new(f"{name} (nested)")
        material_from_json(nested, itf, base_dir, name=nested.name)
        layer.kind = "MATERIAL"
        layer.material = nested
    else:
        raise PresetError(f"{name}: interface type {kind!r} cannot be edited as a stack")


def _fill_medium(layer, med: dict, base_dir: Path) -> None:
    layer.thickness = float(med.get("thickness", 1.0))
    layer.sigma_t, layer.sigma_t_texture = _number(med.get("sigma_t", 0.0), base_dir, "sigma_t")
    layer.albedo, layer.albedo_texture = _colour(med.get("albedo"), base_dir, (0.8, 0.8, 0.8))
    phase = med.get("phase") or {"type": "isotropic"}
    kind = phase.get("type", "isotropic")
    if kind == "isotropic" or (kind == "hg" and float(phase.get("g", 0.0)) == 0.0):
        layer.phase = "ISOTROPIC"
    elif kind == "hg":
        layer.phase = "HG"
        layer.hg_g = float(phase.get("g", 0.0))
    elif kind == "microflake":
        layer.phase = "MICROFLAKE"
        layer.flake_stddev = float(phase.get("stddev", 0.05))
        layer.flake_orientation = [float(v) for v in phase.get("orientation", [1, 0, 0])]
    elif kind == "vmf":
        layer.phase = "VMF"
        layer.vmf_kappa = float(phase.get("kappa", 10.0))
    elif kind == "sggx" and "matrix" not in phase:
        layer.phase = "SGGX"
        layer.sggx_shape = "FLAKE" if phase.get("shape") == "flake" else "FIBER"
        default = [0, 0, 1] if layer.sggx_shape == "FLAKE" else [1, 0, 0]
        layer.flake_orientation = [float(v) for v in phase.get("orientation", default)]
        layer.sggx_roughness = float(phase.get("roughness", 0.3))
    else:
        raise PresetError(f"phase function {kind!r} cannot be edited in the stack editor")


def material_from_json(mat, doc: dict, base_dir: Path, name: str = "") -> None:
    """Replace ``mat``'s Lamina stack with the material described by ``doc``."""
    settings = mat.lamina
    interfaces = doc.get("interfaces") if doc.get("type") == "layered" else [doc]
    media = doc.get("media", []) if doc.get("type") == "layered" else []
    if not interfaces:
        raise PresetError(f"{name}: the stack has no interfaces")
    if len(media) != len(interfaces) - 1:
        raise PresetError(f"{name}: {len(interfaces)} interfaces need {len(interfaces) - 1} media")
    settings.layers.clear()
    for i, itf in enumerate(interfaces):
        layer = add_layer(settings, "DIELECTRIC", i)
        _fill_interface(layer, itf, base_dir, name)
        layer.name = ""
        layer.name = (itf.get("_name") if isinstance(itf, dict) else None) or default_name(settings, layer.kind)
        if i < len(media):
            _fill_medium(layer, media[i], base_dir)
    emission = doc.get("emission")
    if emission is not None and not isinstance(emission, dict):
        peak = max(float(v) for v in emission) if emission else 0.0
        if peak > 0:
            settings.emission_strength = peak
            settings.emission_color = [float(v) / peak for v in emission]
    settings.active_layer = 0
    settings.use_stack = True


# ------------------------------------------------------------------------ operators and menu

class LAMINA_OT_preset_apply(bpy.types.Operator):
    bl_idname = "lamina.preset_apply"
    bl_label = "Apply Material Preset"
    bl_description = "Replace the layer stack of the active material with a preset"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"})

    @classmethod
    def poll(cls, context):
        return getattr(context, "material", None) is not None

    def execute(self, context):
        path = Path(self.filepath)
        try:
            name, doc = read_preset(path)
            material_from_json(context.material, doc, path.parent, name)
        except PresetError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        return {"FINISHED"}


class LAMINA_OT_preset_save(bpy.types.Operator):
    bl_idname = "lamina.preset_save"
    bl_label = "Save Material Preset"
    bl_description = "Save the active material's layer stack as a preset in your preset folder"

    name: StringProperty(name="Name", default="My Material")

    @classmethod
    def poll(cls, context):
        mat = getattr(context, "material", None)
        return mat is not None and len(mat.lamina.layers) > 0 and user_preset_dir() is not None

    def invoke(self, context, event):
        self.name = context.material.name
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        folder = user_preset_dir(create=True)
        notes: list[str] = []
        try:
            material = stack_json(context.material, ImageExporter(None, False, notes))
        except StackError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        path = folder / f"{safe_name(self.name)}.json"
        doc = {"name": self.name, "category": "User", "description": "", "tags": [], "material": material}
        path.write_text(json.dumps(doc, indent=2), encoding="utf-8")
        self.report({"INFO"}, f"Saved preset {path}")
        return {"FINISHED"}


class LAMINA_MT_material_presets(bpy.types.Menu):
    bl_idname = "LAMINA_MT_material_presets"
    bl_label = "Material Presets"

    def draw(self, context):
        layout = self.layout
        files = preset_files()
        for path in files:
            op = layout.operator(LAMINA_OT_preset_apply.bl_idname, text=path.stem.replace("-", " ").title())
            op.filepath = str(path)
        for hook in MENU_HOOKS:
            hook(self, context)
        if not files and not MENU_HOOKS:
            layout.label(text="No presets installed")
        layout.separator()
        layout.operator(LAMINA_OT_preset_save.bl_idname, icon="ADD")


CLASSES = (LAMINA_OT_preset_apply, LAMINA_OT_preset_save, LAMINA_MT_material_presets)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
