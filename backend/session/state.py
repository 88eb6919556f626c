"""A session's scene: the document as last received, its parsed sections, and the renderable
Scene + Accelerator + PathTracer, rebuilt as little as each edit needs.

What an edit of each section rebuilds (``SessionScene.update`` returns the names):

==========  =====================================================================================
camera      the camera only (``PathTracer.set_camera``)
film        the image size (and the pixel filter tables if the filter changed)
render      the settings → a new PathTracer (its tables; the BVH is kept)
materials   the edited materials are parsed again → material/light tables (mesh lights follow)
lights      the lights are parsed again → light tables
world       the world is parsed again → light tables
objects     the triangle soup and the embree BVH, then the tables
meshes      the edited meshes are parsed again, then as objects
==========  =====================================================================================

Everything is parsed with the scene loader's own functions (``scene/loader.py``), so a session
renders exactly what ``render`` renders from the same document. An edit is all-or-nothing: if a
section fails to parse, the previous scene stays built (and is not rendered: the client gets the
error) and the failed sections are parsed again with the next edit.

Scenes far from the origin are moved to the camera of the *first* document (``rebased``) and keep
that offset for the whole session, so camera moves never move the world.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

from ..errors import LaminaError, SceneError
from ..scene import loader
from ..scene.reader import LoadContext, Node
from .protocol import MERGED_SECTIONS, SECTIONS


class FileCache(dict):
    """``LoadContext.cache`` for a long-lived session: decoded image files are kept, and dropped
    when the file changes on disk (modification time or size), so an edited texture is read
    again with the next edit while unchanged ones are never decoded twice."""

    def __init__(self):
        super().__init__()
        self._stamps: dict = {}

    @staticmethod
    def _stamp(path: str):
        try:
            st = os.stat(path)
        except OSError:
            return None
        return st.st_mtime_ns, st.st_size

    def __setitem__(self, key, value):
        if isinstance(key, tuple) and len(key) == 2 and key[0] == "image":
            self._stamps[key] = self._stamp(key[1])
        super().__setitem__(key, value)

    def drop_changed_files(self) -> int:
        dropped = 0
        for key, stamp in list(self._stamps.items()):
            if self._stamp(key[1]) != stamp:
                self.pop(key, None)
                del self._stamps[key]
                dropped += 1
        return dropped


class SessionScene:
    def __init__(self):
        # Told of long preparations (tables of layered stacks solved for the first time on this
        # machine: backend/layered/tabulated.prepare): a callable taking an event dict.
        self.on_event = None
        self.doc: dict | None = None
        self.where = "<session>"
        self.base: Path | None = None
        self.offset = None
        self.ctx: LoadContext | None = None
        self._dirty: set[str] = set()
        # parsed sections
        self.settings = None
        self.film = None                  # (width, height, pixel_filter, crop, transparent)
        self.camera = None
        self.materials: dict = {}         # name -> (entry as received, parsed material)
        self.meshes: dict = {}            # name -> (entry as received, Mesh)
        self.lights: list = []
        self.world = None
        self.material_list: list = []     # the soup's material indices refer to this list
        self.material_names: list = []
        self.named: list = []             # the document's material names (material_list's start)
        self.soup = None
        self.accel = None
        self.bounds = None
        self.scene = None
        self.tracer = None
        self.warnings: list[str] = []

    @property
    def ready(self) -> bool:
        """A scene is built and no edit is waiting to be parsed again."""
        return self.tracer is not None and not self._dirty

    # ------------------------------------------------------------------ edits

    def load(self, data: dict, where: str = "<session scene>", base: str | Path | None = None) -> dict:
        """Replace the whole scene. Returns {part: seconds} of what was built."""
        if not isinstance(data, dict):
            raise SceneError(where, "", "expected a JSON object")
        ctx = LoadContext(where, Path(base) if base else None)
        root = Node(data, "", ctx)
        loader.check_header(root)
        for key in data:
            if key not in SECTIONS and key not in ("format", "version") and not key.startswith("_"):
                raise root.fail(f"unknown field (allowed: {', '.join(('format', 'version') + SECTIONS)})", key)
        ctx.cache = FileCache()
        self.__init__()
        self.where, self.base, self.ctx = where, ctx.base_dir, ctx
        self.doc = {k: data[k] for k in SECTIONS if k in data}
        self.offset = loader.rebase_offset(data)
        self._dirty = set(SECTIONS)
        return self._build()

    def update(self, changes: dict) -> dict:
        """Apply changed sections (``materials``/``meshes`` merge by name, ``null`` removes).
        Returns {part: seconds} of what was rebuilt; raises LaminaError (state kept) on a bad
        section."""
        return self.update_all([changes])

    def update_all(self, batch: list) -> dict:
        """Apply several updates in order, then build once: an update that fails alone and the
        one that fixes it, taken together, build the fixed scene."""
        if self.doc is None:
            raise LaminaError("update before any scene: send a 'scene' command first")
        for changes in batch:
            self._merge(changes)
        return self._build()

    def _merge(self, changes: dict) -> None:
        for key, value in changes.items():
            if key in MERGED_SECTIONS:
                merged = dict(self.doc.get(key) or {})
                for name, entry in value.items():
                    if entry is None:
                        merged.pop(name, None)
                    else:
                        merged[name] = entry
                self.doc[key] = merged
            elif value is None:
                self.doc.pop(key, None)
            else:
                self.doc[key] = value
            self._dirty.add(key)

    # ------------------------------------------------------------------ building

    def _section(self, doc: dict, key: str, required: bool = False) -> Node | None:
        if key not in doc:
            if required:
                raise self.ctx.error(key, "missing required field")
            return None
        return Node(doc[key], key, self.ctx)

    def _parse_named(self, doc: dict, key: str, old: dict, parse, force: bool = False) -> dict:
        node = self._section(doc, key)
        out = {}
        for name, child in (node.entries() if node is not None else []):
            previous = old.get(name)
            if previous is not None and not force and previous[0] == child.value:
                out[name] = previous
            else:
                out[name] = (child.value, parse(child))
        return out

    def _build(self) -> dict:
        dirty = set(self._dirty)
        ctx = self.ctx
        ctx.warnings = []
        timings: dict[str, float] = {}
        t = time.perf_counter()

        def done(part: str):
            nonlocal t
            now = time.perf_counter()
            timings[part] = round(timings.get(part, 0.0) + now - t, 4)
            t = now

        doc = self.doc if self.offset is None else loader.rebase_sections(self.doc, self.offset)
        if self.tracer is not None and dirty <= {"camera", "film", "passes", "views"}:
            return self._view_only(doc, dirty, timings, done)

        settings, film, camera = self.settings, self.film, self.camera
        force_materials = False
        if "render" in dirty or settings is None:
            defaults = ctx.cache.get("layered_defaults")
            settings = loader.parse_settings(self._section(doc, "render"), ctx)
            force_materials = defaults is not None and ctx.cache.get("layered_defaults") != defaults
            done("settings")
        if "film" in dirty or film is None:
            film = loader.parse_film(self._section(doc, "film", required=True))
            done("film")
        if "camera" in dirty or camera is None:
            from ..camera import parse_camera
            camera = parse_camera(self._section(doc, "camera", required=True))
            done("camera")
        self._check_unrendered(doc, dirty)

        materials = self.materials
        if "materials" in dirty or force_materials:
            ctx.cache.drop_changed_files()
            materials = self._parse_named(doc, "materials", self.materials, loader.parse_material, force_materials)
            done("materials")
        meshes = self.meshes
        if "meshes" in dirty:
            from ..geometry.mesh import parse_mesh
            meshes = self._parse_named(doc, "meshes", self.meshes, parse_mesh)
            done("meshes")

        names = list(materials)
        changed_meshes = meshes is not self.meshes and (
            set(meshes) != set(self.meshes) or any(meshes[n] is not self.meshes.get(n) for n in meshes))
        geometry = self.soup is None or "objects" in dirty or changed_meshes or names != self.named
        soup, accel = self.soup, self.accel
        material_list = [materials[n][1] for n in names]
        material_names = list(names)
        if geometry:
            from ..geometry.accel import Accelerator
            soup = loader.flatten_objects(self._section(doc, "objects"), {n: m[1] for n, m in meshes.items()},
                                          material_list, material_names, ctx)
            done("soup")
            accel = Accelerator(soup)
            done("bvh")
        else:
            # Keep the slots flatten_objects appended (the default material of unset slots).
            material_list += self.material_list[len(names):]
            material_names += self.material_names[len(names):]

        lights, world = self.lights, self.world
        if "lights" in dirty:
            lights = loader.parse_lights(self._section(doc, "lights"))
            done("lights")
        if "world" in dirty:
            world = loader.parse_world(self._section(doc, "world"))
            done("world")

        bounds = self.bounds
        if geometry or "lights" in dirty or bounds is None:
            bounds = loader.scene_bounds(soup, lights, camera)
        scene = loader.assemble_scene(ctx, *film, camera, settings, material_list, material_names, soup,
                                      lights, world, bounds=bounds)
        from ..integrator import PathTracer
        from ..layered.tabulated import prepare as prepare_tables
        prepare_tables(material_list, self.on_event or (lambda event: None))
        tracer = PathTracer(scene, accel)
        done("tables")

        # Everything parsed: commit.
        self.settings, self.film, self.camera = settings, film, camera
        self.materials, self.meshes, self.lights, self.world = materials, meshes, lights, world
        self.material_list, self.material_names, self.named = material_list, material_names, names
        self.soup, self.accel, self.bounds = soup, accel, bounds
        self.scene, self.tracer = scene, tracer
        self.warnings = list(ctx.warnings)
        self._dirty = set()
        return timings

    def _check_unrendered(self, doc: dict, dirty: set) -> None:
        """Data passes and named views: the viewport renders neither, but a scene `render`
        accepts is accepted here too, and one it refuses is refused with the same message."""
        if "passes" in dirty:
            from ..passes import parse_passes
            parse_passes(self._section(doc, "passes"))
        if "views" in dirty:
            loader.parse_views(self._section(doc, "views"), None)

    def _view_only(self, doc: dict, dirty: set, timings: dict, done) -> dict:
        """Camera and film edits (and the unrendered passes and views): no table is rebuilt."""
        self._check_unrendered(doc, dirty)
        film, camera = self.film, self.camera
        if "film" in dirty:
            film = loader.parse_film(self._section(doc, "film", required=True))
            done("film")
        if "camera" in dirty:
            from ..camera import parse_camera
            camera = parse_camera(self._section(doc, "camera", required=True))
            done("camera")
        old_filter, scene = self.film[2], self.scene
        rebuild = film[4] != self.film[4] or \
            (film[2].kind, film[2].width) != (old_filter.kind, old_filter.width)
        scene.width, scene.height, scene.pixel_filter, scene.crop, scene.transparent = film
        if rebuild:
            # The filter tables and the transparent-film flag live in the tracer's settings.
            scene.camera = camera
            from ..integrator import PathTracer
            self.tracer = PathTracer(scene, self.accel)
            done("tables")
        elif "camera" in dirty:
            self.tracer.set_camera(camera)
        self.film, self.camera = film, camera
        self._dirty = set()
        return timings
