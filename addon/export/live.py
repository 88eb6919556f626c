"""Scene export for a viewport session: the whole scene once, then only the sections that changed.

``LiveExporter`` keeps what is expensive between depsgraph updates — extracted meshes (``.npz``
files), material JSON and exported images — and throws away exactly what an update invalidates
(``invalidate``: the IDs of ``depsgraph.updates``). Each export walks the depsgraph's object
instances again (cheap: matrices and cache look-ups), builds the document with the same
``SceneExporter`` as F12, and ``changes`` compares it section by section with what the session
already has: only differing sections are sent (``materials`` and ``meshes`` entry by entry). A
changed mesh is written under a new file name, so the session knows to read it again; a mesh
read again with the same content (Blender may flag an object's geometry when only its material
changed) keeps its name, so nothing is sent.
"""
from __future__ import annotations

import copy
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import bpy

from .images import ImageExporter
from .nodes import NodeTranslator
from .scene import SceneExporter, render_json

#: Sections compared entry by entry (a changed entry is sent, a removed one as null).
MERGED = ("materials", "meshes")
SECTIONS = ("film", "camera", "render", "materials", "meshes", "objects", "lights", "world")


@dataclass
class _Mesh:
    name: str | None
    data_name: str              # the data-block (or object) it was read from: a guard against reused pointers
    triangles: int
    owners: set = field(default_factory=set)     # original object names using it


def _data_name(obj) -> str:
    original = obj.original if obj.original is not None else obj
    if obj.type == "MESH" and original.data is not None:
        return "M:" + original.data.name_full
    return "O:" + original.name_full


class _LiveSceneExporter(SceneExporter):
    """A SceneExporter that reads meshes, materials and images through the live caches."""

    def __init__(self, depsgraph, live: "LiveExporter"):
        super().__init__(depsgraph, live.directory)
        self.live = live
        live.images.notes = self.notes
        self.images = live.images
        self.nodes = NodeTranslator(self.images, self.notes)
        self._mesh_names = set(live.mesh_names)

    def material_json(self, mat) -> dict:
        cache = self.live.material_cache
        name = mat.name_full
        if name not in cache:
            cache[name] = super().material_json(mat)
        return copy.deepcopy(cache[name])

    def mesh_for(self, obj):
        key = self.mesh_key(obj)
        if key in self._mesh_keys:
            return self._mesh_keys[key]
        cache = self.live.mesh_cache
        owner = (obj.original or obj).name_full
        entry = cache.get(key)
        if entry is not None and entry.data_name == _data_name(obj):
            entry.owners.add(owner)
            self._mesh_keys[key] = entry.name
            if entry.name is not None:
                self.meshes[entry.name] = {"file": f"{self.mesh_folder}/{entry.name}.npz"}
                self.stats["triangles"] += entry.triangles
                self.stats["meshes"] += 1
            return entry.name
        before = self.stats["triangles"]
        name = super().mesh_for(obj)   # through store_mesh below
        if name is not None:
            self.live.mesh_names.add(name)
        cache[key] = _Mesh(name, _data_name(obj), self.stats["triangles"] - before, {owner})
        return name


    def store_mesh(self, base: str, arrays: dict) -> str:
        """A mesh whose content was written before (same base name) keeps that file and name."""
        digest = hashlib.blake2b(digest_size=16)
        for key in sorted(arrays):
            a = arrays[key]
            digest.update(key.encode() + str(a.dtype).encode() + str(a.shape).encode())
            digest.update(a.tobytes())
        digest = digest.hexdigest()
        known = self.live.mesh_digests
        for name, d in known.items():
            if d == digest and (name == base or name.startswith(base + "_")):
                return name
        name = super().store_mesh(base, arrays)
        known[name] = digest
        self.live.meshes_written += 1
        return name


class LiveExporter:
    def __init__(self, directory: Path):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.images = ImageExporter(self.directory, False, [])
        self.material_cache: dict[str, dict] = {}
        self.mesh_cache: dict[tuple, _Mesh] = {}
        self.mesh_names: set[str] = set()
        self.mesh_digests: dict[str, str] = {}   # mesh name -> digest of the arrays in its file
        self.meshes_written = 0
        self.sent: dict | None = None          # the document the session has (sections)
        self.notes: list[str] = []
        self.stats: dict = {}

    # ------------------------------------------------------------------ invalidation

    def invalidate(self, depsgraph) -> None:
        """Forget what the updates of ``depsgraph`` (a view_update's) make stale."""
        materials = False
        for update in depsgraph.updates:
            data = update.id
            original = getattr(data, "original", None) or data
            if isinstance(data, bpy.types.Object):
                if update.is_updated_geometry:
                    self._drop_meshes(lambda m: original.name_full in m.owners)
                if update.is_updated_shading:
                    materials = True          # slot assignments, object colour
            elif isinstance(data, bpy.types.Mesh):
                if update.is_updated_geometry:
                    name = "M:" + original.name_full
                    self._drop_meshes(lambda m: m.data_name == name)
            elif isinstance(data, bpy.types.Image):
                self.images.forget(original)
                materials = True
            elif isinstance(data, (bpy.types.Material, bpy.types.NodeTree, bpy.types.Texture)):
                materials = True
        if materials:
            self.material_cache.clear()

    def _drop_meshes(self, test) -> None:
        for key in [k for k, m in self.mesh_cache.items() if test(m)]:
            del self.mesh_cache[key]

    # ------------------------------------------------------------------ export

    def export(self, depsgraph, camera: dict, film: dict) -> dict:
        """The whole document for this depsgraph and view."""
        exporter = _LiveSceneExporter(depsgraph, self)
        doc = exporter.build(None, camera=camera, film=film)
        # The session's sample target is Viewport Samples (set_samples); the final render's
        # samples, adaptive sampling and time limit do not apply, so editing them must not
        # restart the viewport: they are left out.
        doc["render"] = {k: v for k, v in render_json(depsgraph.scene).items()
                         if k not in ("spp", "noise_target", "min_spp", "time_limit")}
        self.notes = exporter.notes
        self.stats = dict(exporter.stats)
        self._forget_unused(doc)
        return doc

    def _forget_unused(self, doc: dict) -> None:
        used = set(doc["meshes"])
        for key in [k for k, m in self.mesh_cache.items() if m.name is not None and m.name not in used]:
            del self.mesh_cache[key]
        for name in [n for n in self.mesh_digests if n not in used]:
            del self.mesh_digests[name]

    def changes(self, doc: dict) -> dict:
        """The sections of ``doc`` that differ from what was sent (and remember ``doc`` as sent)."""
        sent = self.sent or {}
        out = {}
        for key in SECTIONS:
            new = doc.get(key)
            old = sent.get(key)
            if key in MERGED:
                new, old = new or {}, old or {}
                diff = {name: entry for name, entry in new.items() if old.get(name) != entry}
                diff.update({name: None for name in old if name not in new})
                if diff:
                    out[key] = diff
            elif new != old:
                out[key] = new
        self.sent = doc
        return out

    def view_changes(self, camera: dict, film: dict) -> dict:
        """Only the view changed (camera and film sections)."""
        sent = self.sent
        out = {}
        if sent.get("camera") != camera:
            out["camera"] = camera
        if sent.get("film") != film:
            out["film"] = film
        if out:
            sent.update(out)
        return out
