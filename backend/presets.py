"""Material presets: a library of named materials usable wherever a material is accepted.

A preset is a JSON file ``<name>.json`` in a preset folder (presets/README.md documents it)::

    {"format": "lamina-preset", "version": 1,
     "name": "car-paint-red", "label": "Car paint, red", "category": "paint",
     "description": "...", "tags": ["coated", "metal"], "source": "...",
     "units": {"sigma_t": "...", ...},
     "material": {<a material in the scene-file schema, docs/materials.md>}}

Preset folders, searched in this order (the first match of a name wins):

* folders listed in ``LAMINA_PRESET_PATH`` (``os.pathsep``-separated) — how the Blender add-on
  passes the user's preset folder (under ``bpy.utils.extension_path_user``) to the backend;
* the shipped library, ``presets/`` next to ``backend/``.

Texture paths inside a preset are relative to the preset file.

Entry points: ``resolve_preset(name, node)`` (the scene loader, for a material given as a string),
``resolve_material(name_or_path)`` (the ``bsdf`` inspector's MATERIAL argument), ``all_presets()``
and ``check_preset()`` (the ``presets`` CLI), and the bpy-free API for the add-on:
``save_user_preset()`` / ``load_user_preset()`` / ``delete_user_preset()``.
"""
from __future__ import annotations

import difflib
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from .errors import LaminaError, SceneError
from .limits import short as _short

SHIPPED = Path(__file__).resolve().parent.parent / "presets"
FORMAT = "lamina-preset"
VERSION = 1
THUMBNAIL_DIR = "thumbnails"          # <preset folder>/thumbnails/<name>.png
NAME_RE = re.compile(r"^[a-z0-9][a-z0-9_-]{0,63}$")
# Folders inside a preset folder that hold assets, never presets.
ASSET_DIRS = frozenset({THUMBNAIL_DIR, "textures", "stage"})


def preset_dirs() -> list[Path]:
    dirs = []
    for entry in os.environ.get("LAMINA_PRESET_PATH", "").split(os.pathsep):
        if entry:
            dirs.append(Path(entry))
    dirs.append(SHIPPED)
    return dirs


def _preset_files(folder: Path) -> list[Path]:
    if not folder.is_dir():
        return []
    out = []
    for p in sorted(folder.rglob("*.json")):
        rel = p.relative_to(folder).parts
        if not any(part in ASSET_DIRS or part.startswith(".") for part in rel[:-1]):
            out.append(p)
    return out


def find_preset(name: str, dirs=None) -> Path | None:
    """The file of preset ``name`` in ``dirs`` (default: ``preset_dirs()``), first match wins."""
    if not name or "/" in name or "\\" in name or name.startswith("."):
        return None            # a name, never a path (no escaping the preset folders)
    if len(name) > 200 or "\x00" in name:
        return None            # no file system has such a name
    for folder in (preset_dirs() if dirs is None else [Path(d) for d in dirs]):
        direct = folder / f"{name}.json"
        try:
            if direct.is_file():
                return direct
        except OSError:
            return None
        for candidate in _preset_files(folder):
            if candidate.stem == name:
                return candidate
    return None


def list_presets(dirs=None) -> list[Path]:
    """Every preset file, one per name (earlier folders shadow later ones), sorted by name.

    ``dirs`` replaces ``preset_dirs()`` (the add-on passes its user folder and the shipped one)."""
    seen, out = set(), []
    for folder in (preset_dirs() if dirs is None else [Path(d) for d in dirs]):
        for p in _preset_files(folder):
            if p.stem not in seen:
                seen.add(p.stem)
                out.append(p)
    return sorted(out, key=lambda p: p.stem)


# --------------------------------------------------------------------------- documents

def load_preset_document(path: Path) -> dict:
    path = Path(path)
    from .scene.reader import read_json
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise LaminaError(f"{path}: cannot read preset: {exc}") from None
    data = read_json(text, str(path))
    if not isinstance(data, dict) or not isinstance(data.get("material"), dict):
        raise LaminaError(f"{path}: a preset file needs a \"material\" object")
    return data


@dataclass
class PresetInfo:
    """A preset's metadata and raw material (the parsed document, not yet a Material)."""

    name: str
    label: str
    category: str
    description: str
    tags: list[str]
    path: Path
    material: dict
    source: str = ""
    units: dict = field(default_factory=dict)

    @property
    def thumbnail(self) -> Path:
        """Where the thumbnail lives (it may not exist yet)."""
        return self.path.parent / THUMBNAIL_DIR / f"{self.name}.png"

    @property
    def shipped(self) -> bool:
        try:
            self.path.resolve().relative_to(SHIPPED.resolve())
            return True
        except ValueError:
            return False

    def summary(self) -> dict:
        return {"name": self.name, "label": self.label, "category": self.category,
                "description": self.description, "tags": list(self.tags), "source": self.source,
                "path": str(self.path), "thumbnail": str(self.thumbnail) if self.thumbnail.is_file() else None,
                "layers": describe_stack(self.material)}


def default_label(name: str) -> str:
    return name.replace("-", " ").replace("_", " ").capitalize()


def read_preset(path: Path) -> PresetInfo:
    """Metadata of one preset (lenient: missing optional fields get defaults)."""
    path = Path(path)
    doc = load_preset_document(path)

    def text(key, default=""):
        v = doc.get(key, default)
        return v if isinstance(v, str) else default

    tags = doc.get("tags", [])
    return PresetInfo(name=path.stem, label=text("label") or default_label(path.stem),
                      category=text("category", "uncategorised") or "uncategorised",
                      description=text("description"),
                      tags=[t for t in tags if isinstance(t, str)] if isinstance(tags, list) else [],
                      path=path, material=doc["material"], source=text("source"),
                      units=doc.get("units") if isinstance(doc.get("units"), dict) else {})


def all_presets() -> list[PresetInfo]:
    return [read_preset(p) for p in list_presets()]


def describe_stack(material: dict) -> str:
    """One line: 'dielectric α0.05 / HG medium / conductor Cu' — for listings."""
    kind = material.get("type", "?")
    if kind != "layered":
        return _describe_interface(material)
    parts = []
    media = material.get("media", []) or []
    for i, iface in enumerate(material.get("interfaces", []) or []):
        parts.append(_describe_interface(iface))
        if i < len(media):
            parts.append(_describe_medium(media[i]))
    return " / ".join(parts)


def _number_text(v) -> str:
    if isinstance(v, dict):
        return "tex"
    if isinstance(v, list):
        return "(" + ",".join(f"{x:g}" if isinstance(x, (int, float)) else "?" for x in v) + ")"
    return f"{v:g}" if isinstance(v, (int, float)) else str(v)


def _describe_interface(m: dict) -> str:
    kind = m.get("type", "?") if isinstance(m, dict) else "?"
    if kind == "null":
        return "null"
    if kind == "layered":
        return "[" + describe_stack(m) + "]"
    bits = [kind]
    if kind == "conductor":
        bits.append(str(m.get("metal", "eta/k" if "eta" in m else "Cu")))
    if kind == "dielectric":
        bits.append(f"η{_number_text(m.get('ior', 1.5))}")
    if "roughness" in m:
        r = f"α{_number_text(m['roughness'])}"
        if "roughness_v" in m:
            r += f"×{_number_text(m['roughness_v'])}"
        bits.append(r)
    if kind == "diffuse" and "color" in m:
        bits.append(_number_text(m["color"]))
    return " ".join(bits)


def _describe_medium(m: dict) -> str:
    if not isinstance(m, dict):
        return "?"
    sigma = m.get("sigma_t", 1.0)
    if sigma == 0:
        return "empty"
    phase = m.get("phase", {"type": "isotropic"})
    kind = phase.get("type", "?") if isinstance(phase, dict) else "?"
    if m.get("albedo", 1.0) in (0, [0, 0, 0]):
        kind = "absorbing"
    thick = "" if m.get("thickness", 1.0) == 1.0 else f"×{_number_text(m.get('thickness'))}"
    return f"{kind} σt{_number_text(sigma)}{thick}"


# --------------------------------------------------------------------------- validation

TOP_LEVEL = ("format", "version", "name", "label", "category", "description", "tags", "source",
             "units", "material")


def check_document(doc: dict, path: Path) -> None:
    """Strict metadata check of a preset document; SceneError naming the file and field."""
    where = str(path)
    if not isinstance(doc, dict):
        raise SceneError(where, "", "expected a JSON object")
    unknown = [k for k in doc if k not in TOP_LEVEL and not k.startswith("_")]
    if unknown:
        raise SceneError(where, unknown[0], f"unknown field (allowed: {', '.join(TOP_LEVEL)})")
    if doc.get("format") != FORMAT:
        raise SceneError(where, "format", f"expected {FORMAT!r}, got {_short(str(doc.get('format')))!r}")
    if doc.get("version") != VERSION:
        raise SceneError(where, "version", f"unsupported preset version {_short(str(doc.get('version')))} "
                                           f"(this Lamina reads version {VERSION})")
    name = doc.get("name")
    if not isinstance(name, str) or not NAME_RE.match(name):
        raise SceneError(where, "name", "expected a name of lower-case letters, digits, '-' and '_' "
                                        f"(at most 64), got {_short(str(name))!r}")
    if name != path.stem:
        raise SceneError(where, "name", f"must equal the file name without .json ({path.stem!r}), got {_short(str(name))!r}")
    for key in ("category", "description"):
        if not isinstance(doc.get(key), str) or not doc[key].strip():
            raise SceneError(where, key, "expected a non-empty string")
    for key in ("label", "source"):
        if key in doc and not isinstance(doc[key], str):
            raise SceneError(where, key, "expected a string")
    tags = doc.get("tags")
    if not isinstance(tags, list) or not all(isinstance(t, str) and t for t in tags):
        raise SceneError(where, "tags", "expected a list of non-empty strings")
    units = doc.get("units", {})
    if not isinstance(units, dict) or not all(isinstance(v, str) for v in units.values()):
        raise SceneError(where, "units", "expected an object of field name → unit text")
    if not isinstance(doc.get("material"), dict):
        raise SceneError(where, "material", "expected a material object")


def parse_material_document(material: dict, where: str, base_dir: Path | None,
                            layered_defaults: dict | None = None, path: str = "material",
                            chain: tuple = ()):
    """Parse a material dict as the scene loader parses a scene's material (the fields every
    material takes included: normal and bump maps, emission sides, pass index); returns
    (Material, warnings). ``chain``: the presets being parsed around this one, outermost first
    (a preset that refers back to one of them is a cycle)."""
    from .scene.loader import parse_material
    from .scene.reader import LoadContext, Node
    ctx = LoadContext(where, base_dir)
    ctx.cache["layered_defaults"] = layered_defaults or {}
    ctx.cache["preset_chain"] = tuple(chain)
    material = parse_material(Node(material, path, ctx))
    return material, ctx.warnings


def check_preset(path: Path):
    """Validate one preset file completely (metadata + material). Returns (Material, warnings)."""
    path = Path(path)
    doc = load_preset_document(path)
    check_document(doc, path)
    return parse_material_document(doc["material"], str(path), path.parent, chain=(path.stem,))


# --------------------------------------------------------------------------- resolution

def close_preset_names(name: str, names: list[str], most: int = 5) -> list[str]:
    """Preset names a mistyped ``name`` probably meant: substrings either way, then names sharing
    a word ("lamina-reference" → the reference stacks), then difflib's close spellings."""
    key = name.lower()
    words = {w for w in key.replace("_", "-").split("-") if len(w) > 2}
    spelled = set(difflib.get_close_matches(key, names, n=most, cutoff=0.6))
    out = [n for n in names if key in n or n in key or words & set(n.split("-")) or n in spelled]
    # Substring matches first, then by similarity of the whole name.
    out.sort(key=lambda n: (not (key in n or n in key), -difflib.SequenceMatcher(None, key, n).ratio()))
    return out[:most]


def require_preset(name: str) -> Path:
    """The file of the preset called ``name`` (find_preset), or LaminaError naming the near misses."""
    path = find_preset(name)
    if path is None:
        raise LaminaError(unknown_preset_message(name))
    return path


def unknown_preset_message(name: str) -> str:
    names = [p.stem for p in list_presets()]
    close = close_preset_names(name, names) if len(name) <= 100 else []
    hint = f" (did you mean: {', '.join(close)}?)" if close else (
        f" (known: {', '.join(names[:12])}{', ...' if len(names) > 12 else ''}; "
        "`python -m backend presets list`)" if names else "")
    from .limits import short
    return f"unknown material preset {short(name)!r}{hint}"


def resolve_preset(name: str, node):
    """Parse preset ``name`` as a material (scene loader hook); errors name the preset file and field."""
    from .scene.inputs import local_file, preset_file
    chain = node.ctx.cache.get("preset_chain", ())
    if name in chain:
        from .limits import short
        cycle = " → ".join(chain[chain.index(name):] + (name,))
        raise node.fail(f"presets refer to each other in a cycle: {short(cycle, 240)}")
    path = preset_file(name, find_preset(name))     # a cluster worker uses the master's preset
    if path is None:
        raise node.fail(unknown_preset_message(name))
    doc = load_preset_document(local_file(path))
    material, warnings = parse_material_document(doc["material"], str(path), path.parent,
                                                 node.ctx.cache.get("layered_defaults", {}),
                                                 chain=chain + (name,))
    node.ctx.warnings.extend(warnings)
    return material


def material_source(name_or_path: str) -> tuple[dict, str, Path, str]:
    """(material dict, file for messages, base folder for textures, field path) of a material argument.

    ``name_or_path`` is a preset name, a preset file, or a JSON file holding one material object.
    """
    text = str(name_or_path)
    p = Path(text)
    if p.suffix.lower() == ".json" or "/" in text or os.sep in text:
        from .scene.reader import path_problem, read_json
        problem = path_problem(text)
        if problem:
            raise LaminaError(f"{text[:60]}: {problem}")
        try:
            found = p.is_file()
            text_data = p.read_text(encoding="utf-8") if found else None
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise LaminaError(f"{p}: cannot read: {exc}") from None
        if not found:
            raise LaminaError(f"{text}: material file not found")
        data = read_json(text_data, str(p))
        if not isinstance(data, dict):
            raise LaminaError(f"{p}: expected a material object")
        if isinstance(data.get("material"), dict) and "type" not in data:
            return data["material"], str(p), p.resolve().parent, "material"     # a preset file
        return data, str(p), p.resolve().parent, ""
    path = find_preset(text)
    if path is None:
        raise LaminaError(unknown_preset_message(text))
    return load_preset_document(path)["material"], str(path), path.parent, "material"


def resolve_material(name_or_path: str, layered_defaults: dict | None = None):
    """A Material from a preset name, a preset file or a material JSON file (``bsdf`` inspector).

    Errors are LaminaError/SceneError naming the file and field; warnings are dropped (use
    ``material_source`` + ``parse_material_document`` to see them).
    """
    material, where, base, field_path = material_source(name_or_path)
    parsed, _ = parse_material_document(material, where, base, layered_defaults, field_path)
    return parsed


# --------------------------------------------------------------------------- writing (add-on API)

def slugify(name: str) -> str:
    """A preset file name from a display name: 'My Car Paint!' → 'my-car-paint'."""
    slug = re.sub(r"[^a-z0-9_-]+", "-", name.strip().lower()).strip("-_")
    return slug[:64] or "preset"


def dumps(doc, indent: int = 2) -> str:
    """Readable JSON: objects one key per line, short lists of numbers/strings on one line."""

    def enc(v, level):
        pad = " " * (indent * level)
        inner = " " * (indent * (level + 1))
        if isinstance(v, dict):
            if not v:
                return "{}"
            if all(not isinstance(x, dict) and not (isinstance(x, list) and any(isinstance(y, (dict, list)) for y in x))
                   for x in v.values()):
                one_line = "{" + ", ".join(f"{json.dumps(k, ensure_ascii=False)}: {enc(x, level + 1)}"
                                           for k, x in v.items()) + "}"
                if len(one_line) + len(inner) <= 100:
                    return one_line
            items = [f"{inner}{json.dumps(k, ensure_ascii=False)}: {enc(x, level + 1)}" for k, x in v.items()]
            return "{\n" + ",\n".join(items) + "\n" + pad + "}"
        if isinstance(v, list):
            flat = all(not isinstance(x, (dict, list)) for x in v)
            one_line = "[" + ", ".join(json.dumps(x, ensure_ascii=False) for x in v) + "]"
            if flat and len(one_line) <= 100:
                return one_line
            if not v:
                return "[]"
            return "[\n" + ",\n".join(inner + enc(x, level + 1) for x in v) + "\n" + pad + "]"
        return json.dumps(v, ensure_ascii=False)

    return enc(doc, 0) + "\n"


def make_document(material: dict, name: str, *, label: str = "", category: str = "user",
                  description: str = "", tags=(), source: str = "", units: dict | None = None) -> dict:
    doc = {"format": FORMAT, "version": VERSION, "name": name,
           "label": label or default_label(name), "category": category or "user",
           "description": description or f"User preset {label or name}.", "tags": list(tags)}
    if source:
        doc["source"] = source
    if units:
        doc["units"] = dict(units)
    doc["material"] = material
    return doc


def save_user_preset(material: dict, name: str, folder: str | Path, *, label: str = "",
                     category: str = "user", description: str = "", tags=(),
                     overwrite: bool = False, validate: bool = True) -> Path:
    """Write ``material`` (a scene-schema material dict) as preset ``name`` into ``folder``.

    ``name`` may be a display name; the file name is its slug (also the preset's name). The
    material is validated first (unless ``validate=False``), so a saved preset always loads.
    Refuses to shadow a shipped preset, and to replace an existing user preset unless
    ``overwrite``. The file is written atomically. Returns the path.
    """
    folder = Path(folder)
    slug = slugify(name)
    if not isinstance(material, dict):
        raise LaminaError("a preset material must be a material object (dict)")
    if (SHIPPED / f"{slug}.json").is_file() or any(p.stem == slug for p in _preset_files(SHIPPED)):
        raise LaminaError(f"{slug!r} is the name of a shipped preset; choose another name")
    target = folder / f"{slug}.json"
    if target.exists() and not overwrite:
        raise LaminaError(f"{target}: a user preset with this name exists (overwrite it explicitly)")
    doc = make_document(material, slug, label=label or name.strip(), category=category,
                        description=description, tags=tags)
    if validate:
        check_document(doc, target)
        parse_material_document(doc["material"], str(target), folder)
    folder.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.tmp")
    tmp.write_text(dumps(doc), encoding="utf-8")
    os.replace(tmp, target)
    return target


def load_user_preset(name: str, folder: str | Path | None = None) -> dict:
    """The whole preset document (metadata + ``material`` dict, exactly as stored).

    With ``folder``, only that folder is searched (the add-on's user folder); otherwise every
    preset folder (user folders from LAMINA_PRESET_PATH first, then the shipped library).
    """
    if folder is not None:
        target = Path(folder) / f"{slugify(name)}.json"
        if not target.is_file():
            raise LaminaError(f"{target}: no such preset")
        return load_preset_document(target)
    return load_preset_document(require_preset(name))


def list_user_presets(folder: str | Path) -> list[PresetInfo]:
    return [read_preset(p) for p in _preset_files(Path(folder))]


def delete_user_preset(name: str, folder: str | Path) -> None:
    target = Path(folder) / f"{slugify(name)}.json"
    if not target.is_file():
        raise LaminaError(f"{target}: no such preset")
    target.unlink()
    thumb = target.parent / THUMBNAIL_DIR / f"{target.stem}.png"
    if thumb.is_file():
        thumb.unlink()
