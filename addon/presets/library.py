"""Preset files: the shipped library and the user's folder (bpy only for the user folder's path).

File handling is the backend's (``backend/presets.py``, bpy-free): the same code reads presets
for scene files, the CLI and this add-on, so a preset the menu shows is one the renderer loads.
User presets live in ``bpy.utils.extension_path_user(<extension>, path="presets")`` — never in
the extension's own folder, which Blender replaces on every update. The render engine passes
that folder to the backend process as ``LAMINA_PRESET_PATH``.
"""
from __future__ import annotations

import json
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import bpy

from ...backend import presets as lib
from ...backend.errors import LaminaError
from .. import launch, preferences

SHIPPED = lib.SHIPPED
USER_CATEGORY = "user"
USER_TEXTURES = "textures"          # <user folder>/textures/<preset name>/ holds a preset's images
VALIDATE_TIMEOUT = 60.0             # seconds for the backend to check a preset (starting Python ~1 s)


class PresetError(Exception):
    """A preset that cannot be read, applied or saved: one line for the user."""


def user_dir(create: bool = False) -> Path | None:
    """The user's preset folder, or None when the add-on is not loaded as an extension."""
    try:
        path = bpy.utils.extension_path_user(preferences.ADDON_ID, path="presets", create=create)
    except (ValueError, RuntimeError, TypeError):       # development load: not an extension
        return None
    return Path(path) if path else None


def folders() -> list[Path]:
    """Search order: the user's folder first (as the backend sees it via LAMINA_PRESET_PATH)."""
    user = user_dir()
    return [user, SHIPPED] if user is not None else [SHIPPED]


def find(name: str) -> Path | None:
    return lib.find_preset(name, folders())


def is_user(path: Path) -> bool:
    user = user_dir()
    if user is None:
        return False
    try:
        Path(path).resolve().relative_to(user.resolve())
        return True
    except ValueError:
        return False


@dataclass(frozen=True)
class Entry:
    """One preset as the menus show it."""

    name: str
    label: str
    category: str
    description: str
    tags: tuple
    path: Path
    thumbnail: Path | None
    user: bool
    error: str = ""


_cache: dict = {"key": None, "entries": []}


def entries() -> list[Entry]:
    """Every preset (user folder first, shadowing shipped names), re-read when files change."""
    paths = lib.list_presets(folders())
    key = []
    for p in paths:
        try:
            key.append((str(p), p.stat().st_mtime_ns))
        except OSError:
            key.append((str(p), 0))
    key = tuple(key)
    if key == _cache["key"]:
        return _cache["entries"]
    out = []
    for p in paths:
        user = is_user(p)
        try:
            info = lib.read_preset(p)
        except LaminaError as exc:
            out.append(Entry(p.stem, lib.default_label(p.stem), USER_CATEGORY if user else "broken",
                             "", (), p, None, user, str(exc)))
            continue
        thumb = info.thumbnail if info.thumbnail.is_file() else None
        out.append(Entry(info.name, info.label, info.category, info.description, tuple(info.tags),
                         p, thumb, user))
    _cache["key"], _cache["entries"] = key, out
    return out


def read_document(path: Path) -> tuple[str, str, dict]:
    """(name, label, material dict) of a preset file; a bare material object is accepted too."""
    path = Path(path)
    try:
        doc = lib.load_preset_document(path)
    except LaminaError as exc:
        bare = _bare_material(path)
        if bare is None:
            raise PresetError(str(exc)) from None
        return path.stem, lib.default_label(path.stem), bare
    name = doc.get("name") if isinstance(doc.get("name"), str) else path.stem
    label = doc.get("label") if isinstance(doc.get("label"), str) else lib.default_label(name)
    return name, label, doc["material"]


def _bare_material(path: Path):
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    return data if isinstance(data, dict) and isinstance(data.get("type"), str) else None


def texture_folder(folder: Path, name: str) -> Path:
    return Path(folder) / USER_TEXTURES / lib.slugify(name)


def write(material: dict, name: str, folder: Path, **meta) -> Path:
    """Write a user preset file (backend.presets.save_user_preset, without loading the material:
    that needs the renderer's parsers, which stay out of Blender — see ``validate``)."""
    try:
        return lib.save_user_preset(material, name, folder, validate=False, **meta)
    except LaminaError as exc:
        raise PresetError(str(exc)) from None


def backend_environment() -> dict:
    """The environment of a backend child process: its import paths, the user preset folder and
    the compiled-kernel cache (launch.user_environment)."""
    from ..engine.job import child_environment          # bpy-free; engine ranks above presets
    return child_environment(launch.user_environment() or None)


def validate(path: Path) -> list[str]:
    """Check a preset file with the backend in a child process (``presets validate --json``):
    metadata, material schema, textures. Returns the warnings; PresetError with the backend's
    message if the file would not load."""
    cmd = [launch.python_executable(), "-m", "backend", "presets", "validate", str(path), "--json"]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, env=backend_environment(),
                              timeout=VALIDATE_TIMEOUT, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise PresetError(f"cannot run the renderer to check the preset: {exc}") from None
    try:
        records = json.loads(proc.stdout)["presets"]
    except (ValueError, KeyError, TypeError):
        lines = [l for l in proc.stderr.splitlines() if l.strip()]
        raise PresetError(lines[-1] if lines else f"the preset check exited with status {proc.returncode}") from None
    bad = [r for r in records if not r.get("ok")]
    if bad:
        raise PresetError(str(bad[0].get("error")))
    return [w for r in records for w in r.get("warnings", [])]


def delete(name: str, folder: Path) -> None:
    """Delete a user preset, its thumbnail and the images saved with it."""
    try:
        lib.delete_user_preset(name, folder)
    except LaminaError as exc:
        raise PresetError(str(exc)) from None
    shutil.rmtree(texture_folder(folder, name), ignore_errors=True)


def slugify(name: str) -> str:
    return lib.slugify(name)


def clear_cache() -> None:
    _cache["key"] = None
