"""Preset thumbnails as icons (``bpy.utils.previews``), loaded on first use and kept per file version."""
from __future__ import annotations

from pathlib import Path

import bpy
import bpy.utils.previews

GENERIC_ICON = "MATERIAL"          # user presets without a thumbnail
_collection = None


def icon_id(path: Path | None) -> int:
    """The icon id of a thumbnail file, 0 when there is none (draw GENERIC_ICON instead)."""
    if path is None or _collection is None:
        return 0
    try:
        key = f"{path}|{Path(path).stat().st_mtime_ns}"     # a re-rendered thumbnail is a new icon
    except OSError:
        return 0
    item = _collection.get(key)
    if item is None:
        item = _collection.load(key, str(path), "IMAGE")
    return item.icon_id


def icon_args(path: Path | None) -> dict:
    """Keyword arguments for ``layout.operator``/``label``: the thumbnail, else the generic icon."""
    ident = icon_id(path)
    return {"icon_value": ident} if ident else {"icon": GENERIC_ICON}


def register():
    global _collection
    _collection = bpy.utils.previews.new()


def unregister():
    global _collection
    if _collection is not None:
        bpy.utils.previews.remove(_collection)
    _collection = None
