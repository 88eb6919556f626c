"""Scene-file field paths → the Blender names users know (no bpy).

The backend reports problems by file and field path (``…/lamina-x/scene/scene.json:
materials.Wood.interfaces[1].color: cannot read image …``). The export knows which Blender
object, material, light, world and shader node every part of the document came from; this
module keeps that as a map from field path to a label, and rewrites the backend's messages with
it: ``material 'Wood', node 'Image Texture': cannot read image …``.

Texture references are labelled by the exporter when it creates them (``ImageExporter.label``);
everything else is labelled from the document's own structure (material keys, ``_name``).
"""
from __future__ import annotations

import re

_PATH = re.compile(r"^(?P<file>.*?\.json): (?P<field>[A-Za-z_][^:]*?): (?P<rest>.*)$", re.S)
_FILE_ONLY = re.compile(r"^(?P<file>.*?\.json): (?P<rest>.*)$", re.S)


def _join(path: str, key) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


class FieldNames:
    """Field path → label (``material 'Wood', node 'Image Texture'``)."""

    def __init__(self):
        self.labels: dict[str, str] = {}

    def collect(self, doc: dict, texture_labels: dict, default_slot: str, world_name: str | None) -> "FieldNames":
        for key, mat in (doc.get("materials") or {}).items():
            base = _join("materials", key)
            name = "the default material" if key == default_slot else f"material '{key}'"
            self.labels[base] = name
            self._textures(mat, base, name, texture_labels)
        for name, _ in (doc.get("meshes") or {}).items():
            users = [o.get("_name") for o in doc.get("objects", []) if o.get("mesh") == name]
            self.labels[_join("meshes", name)] = (f"mesh of object '{users[0]}'" if users else f"mesh '{name}'")
        for i, obj in enumerate(doc.get("objects") or []):
            self.labels[_join("objects", i)] = f"object '{obj.get('_name', i)}'"
        for i, light in enumerate(doc.get("lights") or []):
            name = f"light '{light.get('_name', i)}'"
            self.labels[_join("lights", i)] = name
            ies = light.get("ies")
            if isinstance(ies, dict):
                # The profile's source as the user set it: a Cycles IES Texture node, or the
                # file or text chosen in Lamina's light panel.
                node = ies.get("_node")
                self.labels[_join(_join("lights", i), "ies")] = (
                    f"{name}, node '{node}'" if node else f"{name}, IES profile set in Lamina's light panel")
        world = doc.get("world")
        if isinstance(world, dict):
            label = f"world '{world_name}'" if world_name else "the world"
            self.labels["world"] = label
            self._textures(world, "world", label, texture_labels)
        return self

    def _textures(self, value, path: str, owner: str, texture_labels: dict) -> None:
        if isinstance(value, dict):
            entry = texture_labels.get(id(value))
            if entry is not None and entry[0] is value:
                self.labels[path] = f"{owner}, {entry[1]}"
            for key, sub in value.items():
                self._textures(sub, _join(path, key), owner, texture_labels)
        elif isinstance(value, list):
            for i, sub in enumerate(value):
                self._textures(sub, _join(path, i), owner, texture_labels)

    def label_for(self, field: str) -> tuple[str | None, str]:
        """The longest labelled prefix of ``field`` and what is left of the path after it."""
        best = None
        for path in self.labels:
            if field == path or field.startswith(path + ".") or field.startswith(path + "["):
                if best is None or len(path) > len(best):
                    best = path
        if best is None:
            return None, field
        return self.labels[best], field[len(best):].lstrip(".")

    def describe(self, message: str) -> str:
        """A backend message with the scene file and field path replaced by Blender names."""
        text = message.strip()
        m = _PATH.match(text)
        if m:
            label, rest_path = self.label_for(m.group("field").strip())
            if label is not None:
                where = label + (f" ({rest_path})" if rest_path and ", node" not in label
                                 and ", image" not in label and ", interface" not in label
                                 and ", IES" not in label else "")
                return f"{where}: {m.group('rest')}"
            return f"{m.group('field')}: {m.group('rest')}"
        m = _FILE_ONLY.match(text)
        if m:
            return m.group("rest")
        return text
