"""Material presets: resolve a preset name to a material anywhere a material is accepted.

A preset is a JSON file ``<name>.json`` under one of the preset folders:

* the repository's / extension's ``presets/`` folder (shipped library),
* folders listed in the environment variable ``LAMINA_PRESET_PATH`` (``os.pathsep``-separated),
  which is how the Blender add-on passes the user's preset folder to the backend.

File shape (see presets/README.md): ``{"name": ..., "category": ..., "description": ...,
"tags": [...], "material": {<material, same schema as scene files>}}``.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from .errors import LaminaError

SHIPPED = Path(__file__).resolve().parent.parent / "presets"


def preset_dirs() -> list[Path]:
    dirs = []
    for entry in os.environ.get("LAMINA_PRESET_PATH", "").split(os.pathsep):
        if entry:
            dirs.append(Path(entry))
    dirs.append(SHIPPED)
    return dirs


def find_preset(name: str) -> Path | None:
    for folder in preset_dirs():
        if not folder.is_dir():
            continue
        direct = folder / f"{name}.json"
        if direct.is_file():
            return direct
        for candidate in sorted(folder.rglob(f"{name}.json")):
            return candidate
    return None


def list_presets() -> list[Path]:
    seen, out = set(), []
    for folder in preset_dirs():
        if folder.is_dir():
            for p in sorted(folder.rglob("*.json")):
                if p.stem not in seen:
                    seen.add(p.stem)
                    out.append(p)
    return out


def load_preset_document(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LaminaError(f"{path}: cannot read preset: {exc}") from None
    if not isinstance(data, dict) or not isinstance(data.get("material"), dict):
        raise LaminaError(f"{path}: a preset file needs a \"material\" object")
    return data


def resolve_preset(name: str, node):
    """Parse preset ``name`` as a material; errors name the preset file and field."""
    from .materials import load_all
    from .scene.reader import LoadContext, Node, dispatch

    path = find_preset(name)
    if path is None:
        known = ", ".join(p.stem for p in list_presets()[:20])
        raise node.fail(f"unknown material preset {name!r}" + (f" (known: {known}, ...)" if known else ""))
    doc = load_preset_document(path)
    ctx = LoadContext(str(path), path.parent)
    ctx.cache["layered_defaults"] = node.ctx.cache.get("layered_defaults", {})
    material = dispatch(Node(doc["material"], "material", ctx), load_all())
    node.ctx.warnings.extend(ctx.warnings)
    return material
