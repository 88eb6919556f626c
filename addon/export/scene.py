"""Depsgraph → one scene description folder: ``scene.json`` + ``meshes/*.npz`` + ``textures/``.

Meshes are extracted once per evaluated data-block (instances share them), objects are
(mesh, transform, material slots) triples, and everything Lamina cannot represent is collected in
``ExportResult.notes`` and reported once by the caller.
"""
from __future__ import annotations

import json
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

from ...backend.render_settings import SETTINGS
from ..util import matrix_rows
from .camera import CameraError, camera_json, film_json, film_size
from .images import ImageExporter, safe_name
from .lights import light_json
from .linking import LIGHT_RAYS, linking_source, resolve, visibility_fields
from .mesh import mesh_arrays, sanitise, write_npz
from .motion import deformation_note, motion_rows
from .names import FieldNames
from .nodes import DEFAULT_MATERIAL, NodeTranslator, volume_note
from .passes import passes_json
from .preset_link import edited_note, linked_json
from .stack import StackError, stack_json
from .unsupported import light_data_notes, object_notes, scene_notes
from .world import world_json

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
UNSUPPORTED_GEOMETRY = {"CURVES": "hair curves", "POINTCLOUD": "point clouds", "VOLUME": "volumes",
                        "GREASEPENCIL": "grease pencil"}
DEFAULT_SLOT = "__lamina_default"
# Blender's material-preview scene has a checker floor that is hidden from camera rays through
# a Light Path node; Lamina shows it to reflections only, with a plain grey diffuse material.
PREVIEW_FLOOR = "FloorHidden"


class ExportError(Exception):
    """The scene cannot be exported (no camera, a broken stack...): one clear message."""


@dataclass
class ExportResult:
    path: Path
    width: int
    height: int
    crop: list | None
    notes: list[str] = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    names: FieldNames = field(default_factory=FieldNames)

    def warning_text(self, limit: int = 12, extra: list[str] | None = None) -> str | None:
        """The render's one warning: the export's notes plus ``extra`` (the renderer's warnings,
        already in Blender names)."""
        return warning_text(list(self.notes) + list(extra or []), limit)

    def describe(self, message: str) -> str:
        """A renderer message with scene-file paths replaced by Blender names (names.py)."""
        return self.names.describe(message)


def warning_text(notes: list[str], limit: int = 12) -> str | None:
    """All notes in one message, grouped by the data-block they are about:
    ``Lamina ignored or approximated: material 'A' (x; y), world 'W' (z)``."""
    if not notes:
        return None
    groups: dict[str, list[str]] = {}
    for note in dict.fromkeys(notes):
        subject, sep, what = note.partition(": ")
        if not sep or "'" not in subject:
            subject, what = "", note
        groups.setdefault(subject, []).append(what)
    parts = [f"{subject} ({'; '.join(items)})" if subject else "; ".join(items)
             for subject, items in groups.items()]
    shown = ", ".join(parts[:limit])
    more = f", and {len(parts) - limit} more" if len(parts) > limit else ""
    return f"Lamina ignored or approximated: {shown}{more}"


def render_json(scene, *, samples: int | None = None, seed_offset: int = 0) -> dict:
    s = scene.lamina
    out = {}
    for st in SETTINGS:                    # Blender's property of each (backend/render_settings.py)
        if st.property_name is not None:
            value = getattr(s, st.property_name)
            out[st.name] = value.lower() if st.kind is str else st.kind(value)
    if samples is not None:
        out["spp"] = int(samples)
    out["seed"] += int(seed_offset)
    out["missing_textures"] = "error" if s.fail_on_missing_textures else "magenta"
    layered = {}
    if s.estimator != "AUTOMATIC":
        layered["estimator"] = {"BIDIRECTIONAL": "bi", "UNIDIRECTIONAL": "uni"}[s.estimator]
    if s.pdf_mode != "LOBES":
        layered["pdf"] = {"APPROXIMATE": "approx", "STOCHASTIC": "stochastic"}[s.pdf_mode]
    if layered:
        out["layered"] = layered
    return out


class SceneExporter:
    def __init__(self, depsgraph, directory: Path | None, *, copy_textures: bool = False,
                 mesh_folder: str = "meshes", preview: bool = False):
        self.depsgraph = depsgraph
        self.preview = preview
        self.mesh_folder = mesh_folder
        # The viewport depsgraph (File > Export) still includes objects hidden for rendering.
        self.viewport = getattr(depsgraph, "mode", "RENDER") == "VIEWPORT"
        self.scene = depsgraph.scene
        self.directory = Path(directory) if directory is not None else None
        self.notes: list[str] = []
        self.images = ImageExporter(self.directory, copy_textures, self.notes)
        self.nodes = NodeTranslator(self.images, self.notes)
        self.materials: dict[str, dict] = {}
        self.meshes: dict[str, dict] = {}
        self._mesh_keys: dict = {}
        self._mesh_names: set[str] = set()
        self.objects: list[dict] = []
        self.lights: list[dict] = []
        self._linking: list = []          # (entry, collections) resolved once all are exported
        self.stats = {"triangles": 0, "meshes": 0, "instances": 0}
        self.names = FieldNames()
        #: Motion blur: {object name: matrices over the shutter} (export/motion.py), or None.
        self.motion: dict | None = None
        self._instances_noted = False

    # ---------------------------------------------------------------- materials

    def material_name(self, mat) -> str:
        if mat is None:
            self.materials.setdefault(DEFAULT_SLOT, dict(DEFAULT_MATERIAL))
            return DEFAULT_SLOT
        name = mat.name_full
        if self.preview and mat.name.startswith(PREVIEW_FLOOR):
            self.materials.setdefault(name, {"type": "diffuse", "color": [0.5, 0.5, 0.5]})
            return name
        if name not in self.materials:
            self.materials[name] = self.material_json(mat)
        return name

    def material_json(self, mat) -> dict:
        out = self._material_json(mat)
        # Emission from the front side only (the material's "Emit From"); Cycles' default is both.
        settings = getattr(mat, "lamina", None)
        emits = out.get("type") == "emission" or "emission" in out
        if settings is not None and getattr(settings, "emission_sides", "BOTH") == "FRONT" and emits:
            out = dict(out, emission_sides="front")
        if int(getattr(mat, "pass_index", 0)) > 0 and isinstance(out, dict):
            out = dict(out, pass_index=int(mat.pass_index))      # the Material Index pass
        return out

    def _material_json(self, mat) -> dict:
        note = volume_note(mat)
        if note is not None and not self.preview:
            self.notes.append(note)
        settings = getattr(mat, "lamina", None)
        if settings is not None and settings.use_stack:
            note = edited_note(mat)
            if note:
                self.notes.append(note)
            try:
                return stack_json(mat, self.images, linked=linked_json(self.images))
            except StackError as exc:
                raise ExportError(f"material '{mat.name}': {exc}") from None
        return self.nodes.material(mat)

    # ---------------------------------------------------------------- geometry

    @staticmethod
    def mesh_key(obj) -> tuple:
        """What identifies an evaluated object's mesh: its mesh data-block (shared by instances)
        or, for curves, text and the like, the object."""
        if obj.type == "MESH":
            return ("mesh", obj.data.as_pointer())
        return ("object", obj.original.as_pointer() if obj.original else obj.as_pointer())

    def mesh_for(self, obj) -> str | None:
        """The mesh entry name for an evaluated object, extracting its mesh the first time."""
        key = self.mesh_key(obj)
        if key in self._mesh_keys:
            return self._mesh_keys[key]
        if obj.type == "MESH":
            arrays = mesh_arrays(obj.data)
        else:
            try:
                me = obj.to_mesh()
            except RuntimeError:
                me = None
            arrays = mesh_arrays(me) if me is not None else None
            obj.to_mesh_clear()
        name = None
        if arrays is not None:
            base = safe_name(obj.data.name if obj.type == "MESH" else obj.name)
            arrays = sanitise(arrays, base, self.notes)
            name = self.store_mesh(base, arrays)
            self.stats["triangles"] += len(arrays["indices"])
            self.stats["meshes"] += 1
            self.meshes[name] = {"file": f"{self.mesh_folder}/{name}.npz"}
        self._mesh_keys[key] = name
        return name

    def unique_mesh_name(self, base: str) -> str:
        name, n = base, 1
        while name in self._mesh_names:
            n += 1
            name = f"{base}_{n}"
        self._mesh_names.add(name)
        return name

    def store_mesh(self, base: str, arrays: dict) -> str:
        """Name a new mesh entry and write its file (when exporting to a folder)."""
        name = self.unique_mesh_name(base)
        if self.directory is not None:
            folder = self.directory / self.mesh_folder
            folder.mkdir(parents=True, exist_ok=True)
            write_npz(folder / f"{name}.npz", arrays)
        return name

    def add_instance(self, inst) -> None:
        obj = inst.object
        kind = obj.type
        if self.viewport and not inst.is_instance and obj.original is not None and obj.original.hide_render:
            return
        if kind == "LIGHT":
            entry = light_json(obj, inst.matrix_world.copy(), self.notes)
            if self.motion and not inst.is_instance and motion_rows(self.motion.get(obj.name)):
                self.notes.append(f"light '{obj.name}': moving lights are not motion-blurred "
                                  f"(rendered where it is at the frame)")
            if entry is not None:
                entry.update(visibility_fields(obj, LIGHT_RAYS))
                self._linking.append((entry, linking_source(obj, blockers=True)))
                self.lights.append(entry)
                if not self.preview:
                    self.notes.extend(object_notes(obj, "light") + light_data_notes(obj))
            return
        if kind in UNSUPPORTED_GEOMETRY:
            self.notes.append(f"object '{obj.name}': {UNSUPPORTED_GEOMETRY[kind]} are not supported (skipped)")
            return
        if kind not in GEOMETRY_TYPES:
            return
        if not inst.is_instance and not inst.show_self:
            return
        original = obj.original if obj.original is not None else obj
        holdout = bool(getattr(original, "is_holdout", False) or getattr(obj, "is_holdout", False))
        mesh = self.mesh_for(obj)
        if mesh is None:
            return
        slots = [self.material_name(slot.material) for slot in obj.material_slots]
        if not slots:
            slots = [self.material_name(None)]
        entry = {"name": obj.name, "_name": obj.name, "mesh": mesh,
                 "to_world": matrix_rows(inst.matrix_world.copy()), "materials": slots}
        if holdout:
            entry["holdout"] = True
        if self.motion is not None:
            if inst.is_instance:
                if not self._instances_noted:
                    self._instances_noted = True
                    self.notes.append("instances (particles, collection instances, geometry nodes "
                                      "instances) are not motion-blurred (rendered at the frame)")
            else:
                rows = motion_rows(self.motion.get(obj.name))
                if rows is not None:
                    entry["motion"] = rows
                note = deformation_note(original)
                if note and not self.preview:
                    self.notes.append(note)
        if int(getattr(original, "pass_index", 0)) > 0:
            entry["pass_index"] = int(original.pass_index)      # the Object Index pass
        hidden_floor = self.preview and any(
            slot.material is not None and slot.material.name.startswith(PREVIEW_FLOOR) for slot in obj.material_slots)
        if not getattr(obj, "visible_camera", True) or hidden_floor:
            entry["visible_camera"] = False
        if not self.preview:
            entry.update(visibility_fields(obj))
            self._linking.append((entry, linking_source(obj, blockers=False)))
        if not self.preview:
            self.notes.extend(object_notes(obj, "object"))
        self.objects.append(entry)
        self.stats["instances"] += 1

    # ---------------------------------------------------------------- whole scene

    def build(self, camera_object, *, samples=None, seed_offset=0, camera: dict | None = None,
              film: dict | None = None, views: dict | None = None) -> dict:
        """The scene document. ``camera``/``film`` given (a viewport's view): used instead of
        the scene camera's and the render resolution's. ``views``: view name → camera (stereo /
        multi-view, made by the engine, which knows each view's eye)."""
        scene = self.scene
        if camera is None:
            if camera_object is None:
                raise ExportError("the scene has no active camera (set one in Scene properties)")
            try:
                camera = camera_json(camera_object, scene)
            except CameraError as exc:
                raise ExportError(str(exc)) from None
            if self.motion is not None:
                rows = motion_rows(self.motion.get(camera_object.name), rigid=True)
                if rows is not None:
                    camera["motion"] = rows
        if film is None:
            width, height = film_size(scene.render)
            film = film_json(scene, width, height)
        for inst in self.depsgraph.object_instances:
            self.add_instance(inst)
        exported = {o["name"] for o in self.objects}
        for entry, source in self._linking:
            if source:
                entry["light_linking"] = resolve(source, exported)
        if not self.preview:
            self.notes.extend(scene_notes(scene, getattr(self.depsgraph, "view_layer", None)))
            if getattr(scene.render, "use_motion_blur", False) and self.motion is None \
                    and scene.render.motion_blur_shutter > 0:
                self.notes.append(f"scene '{scene.name}': motion blur (not rendered here: the "
                                  f"viewport shows the frame's instant)")
        doc = {"format": "lamina-scene", "version": 1,
               "_generator": "Lamina Blender add-on",
               "film": film,
               "camera": camera,
               "render": render_json(scene, samples=samples, seed_offset=seed_offset),
               "materials": self.materials,
               "meshes": self.meshes,
               "objects": self.objects,
               "lights": self.lights,
               "world": world_json(scene.world, self.images, self.notes)}
        if views:
            doc["views"] = views
        if not self.preview:
            passes = passes_json(getattr(self.depsgraph, "view_layer", None), scene.world)
            if passes:
                doc["passes"] = passes
        self.names = FieldNames().collect(doc, self.images.labels, DEFAULT_SLOT,
                                          scene.world.name if scene.world is not None else None)
        return doc


_NUMBER_LIST = re.compile(r"\[\s*(-?[\d.eE+-]+(?:,\s*-?[\d.eE+-]+)*)\s*\]")


def dumps(doc: dict) -> str:
    """Indented JSON with lists of numbers kept on one line (readable matrices and colours)."""
    text = json.dumps(doc, indent=1, allow_nan=False)
    return _NUMBER_LIST.sub(lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]", text)


def export_scene(depsgraph, directory, *, camera_object=None, samples: int | None = None,
                 copy_textures: bool = False, seed_offset: int = 0,
                 filename: str = "scene.json", mesh_folder: str = "meshes",
                 preview: bool = False, views: dict | None = None, frame_set=None) -> ExportResult:
    """Write the scene of ``depsgraph`` into ``directory``; raises ExportError for fatal problems.
    ``frame_set(frame, subframe)`` evaluates the scene at another time (RenderEngine.frame_set,
    Scene.frame_set): with motion blur on, objects and the camera are sampled over the shutter."""
    t0 = time.perf_counter()
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    exporter = SceneExporter(depsgraph, directory, copy_textures=copy_textures, mesh_folder=mesh_folder,
                             preview=preview)
    from .motion import sample, shutter_times
    times = shutter_times(depsgraph.scene) if frame_set is not None and not preview else None
    if times:
        exporter.motion = sample(depsgraph, frame_set, times)
    camera_object = camera_object if camera_object is not None else depsgraph.scene.camera
    doc = exporter.build(camera_object, samples=samples, seed_offset=seed_offset, views=views)
    path = directory / filename
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(dumps(doc), encoding="utf-8")
    tmp.replace(path)
    stats = dict(exporter.stats, seconds=round(time.perf_counter() - t0, 4))
    film = doc["film"]
    return ExportResult(path, film["width"], film["height"], film.get("crop"), exporter.notes, stats,
                        exporter.names)
