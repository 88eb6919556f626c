"""The link between a material's stack and the preset it was loaded from.

Applying a preset stores the preset's material JSON with the material, plus a fingerprint of the
stack right after conversion. While the stack still has that fingerprint, export writes the
preset's JSON *exactly* (texture paths resolved against the preset's folder), so fields the
stack editor cannot show (a roughness texture in α, a textured fibre orientation, per-material
estimator options, ...) are rendered as the preset defines them. Any edit changes the
fingerprint: the stack as edited is exported, and a note lists the preset fields it lacks.
"""
from __future__ import annotations

import json
from pathlib import Path

import bpy

from ..presets import library
from .stack import StackError, stack_json

NONE, EXACT, EDITED = "NONE", "EXACT", "EDITED"


class _FingerprintImages:
    """Stands in for the ImageExporter: an image is identified by its data-block name only, so a
    fingerprint does not change when the .blend (and with it relative image paths) moves."""

    def texture(self, image, *, scale=None, squared=False, channel=None):
        if image is None:
            return None
        return {"texture": f"<image {image.name}>", "scale": scale, "squared": squared, "channel": channel}


def fingerprint(material) -> str:
    try:
        doc = stack_json(material, _FingerprintImages())
    except StackError:
        return ""
    return json.dumps(doc, sort_keys=True)


def state(material) -> str:
    settings = material.lamina
    if not settings.preset_material:
        return NONE
    return EXACT if fingerprint(material) == settings.preset_fingerprint else EDITED


def dropped(material) -> list[str]:
    try:
        value = json.loads(material.lamina.preset_dropped or "[]")
    except ValueError:
        return []
    return [str(v) for v in value] if isinstance(value, list) else []


def attach(material, *, name: str, label: str, path: Path | str, doc: dict, dropped_fields: list[str]) -> None:
    settings = material.lamina
    settings.preset_name = name
    settings.preset_label = label
    settings.preset_file = str(path)
    settings.preset_material = json.dumps(doc)
    settings.preset_dropped = json.dumps(list(dropped_fields))
    settings.preset_fingerprint = fingerprint(material)


def detach(material) -> None:
    settings = material.lamina
    for prop in ("preset_name", "preset_label", "preset_file", "preset_material", "preset_fingerprint",
                 "preset_dropped"):
        setattr(settings, prop, "")


def preset_path(settings) -> Path:
    return Path(bpy.path.abspath(settings.preset_file, library=settings.id_data.library))


def base_dirs(settings) -> list[Path]:
    """Folders a linked preset's relative texture paths may be relative to: where the preset was
    read from, then where a preset of that name is found now (another machine, an updated add-on)."""
    out = []
    if settings.preset_file:       # may be relative to the .blend ("//..."), like image paths
        out.append(preset_path(settings).parent)
    found = library.find(settings.preset_name) if settings.preset_name else None
    if found is not None and found.parent not in out:
        out.append(found.parent)
    return out


def resolve_texture(file: str, bases: list[Path]) -> Path:
    p = Path(file)
    if p.is_absolute() or not bases:
        return p
    for base in bases:
        if (base / p).is_file():
            return base / p
    return bases[0] / p              # missing everywhere: the backend reports this path


def rebase_textures(value, bases: list[Path], place):
    """A copy of a material dict with every texture file passed through ``place(Path) → str``."""
    if isinstance(value, dict):
        out = {k: rebase_textures(v, bases, place) for k, v in value.items()}
        if isinstance(value.get("texture"), str):
            out["texture"] = place(resolve_texture(value["texture"], bases))
        return out
    if isinstance(value, list):
        return [rebase_textures(v, bases, place) for v in value]
    return value


def linked_material(material, images) -> dict | None:
    """The preset's material JSON if the stack is unchanged since it was applied, else None."""
    settings = getattr(material, "lamina", None)
    if settings is None or not settings.preset_material or state(material) != EXACT:
        return None
    try:
        doc = json.loads(settings.preset_material)
    except ValueError:
        return None
    place = images.file if images is not None and hasattr(images, "file") else str
    return rebase_textures(doc, base_dirs(settings), place)


def linked_json(images):
    """``stack_json``'s ``linked`` for an export writing textures through ``images``."""
    return lambda material: linked_material(material, images)


def edited_note(material) -> str | None:
    """The export note for a linked material whose stack was edited (None if nothing is lost)."""
    if state(material) != EDITED:
        return None
    lost = dropped(material)
    if not lost:
        return None
    shown = "; ".join(lost[:4]) + (f"; and {len(lost) - 4} more" if len(lost) > 4 else "")
    return (f"material '{material.name}': edited after applying preset '{material.lamina.preset_name}', "
            f"so preset fields the stack editor cannot show are not exported ({shown})")
