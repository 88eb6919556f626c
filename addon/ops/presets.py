"""Material presets in the layer-stack panel: apply, save as a user preset, delete, browse.

Presets are JSON files in the shared material schema (presets/README.md). Applying one converts
its material into the stack properties (presets/convert.py: whatever the editor cannot show is
reported) and keeps the preset's JSON with the material, so export writes an unedited preset
exactly (export/preset_link.py). User presets are saved in the extension's user directory
(presets/library.py), never inside the extension. Other code can add menu entries by appending a
``draw(menu, context)`` function to ``MENU_HOOKS``.
"""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from ..export import preset_link
from ..export.images import ImageExporter
from ..export.stack import StackError, stack_json
from .. import launch, preferences
from ..presets import library, previews, thumbnail_jobs
from ..presets.convert import material_from_json  # noqa: F401  (re-exported for scripts and tests)
from ..presets.library import PresetError

SHIPPED = library.SHIPPED
MENU_HOOKS: list = []          # draw(menu, context) functions added by other code
MENU_ROWS = 16                 # rows per menu column before a new column starts
SHOWN_DROPPED = 3              # fields listed in a report before "and N more"


def user_preset_dir(create: bool = False) -> Path | None:
    return library.user_dir(create)


def _summary(fields: list[str]) -> str:
    shown = "; ".join(fields[:SHOWN_DROPPED])
    return shown + (f"; and {len(fields) - SHOWN_DROPPED} more" if len(fields) > SHOWN_DROPPED else "")


def apply_preset(material, path: Path) -> tuple[str, list[str]]:
    """Convert preset ``path`` into ``material``'s stack and link it; returns (label, dropped)."""
    path = Path(path)
    name, label, doc = library.read_document(path)
    dropped = material_from_json(material, doc, path.parent, label)
    preset_link.attach(material, name=name, label=label, path=path, doc=doc, dropped_fields=dropped)
    material.update_tag()          # Python edits of ID properties do not tag the depsgraph themselves
    return label, dropped


class _PresetImages(ImageExporter):
    """Images of a saved preset go to <user folder>/textures/<preset>/, referenced relative to
    the preset file (as the preset format wants). They are first written to a staging folder,
    so an overwritten preset's own images can still be read while the new version is made."""

    def __init__(self, folder: Path, texture_dir: Path, staging: Path, notes: list[str]):
        super().__init__(folder, True, notes)
        self.texture_dir = texture_dir
        self.staging = staging

    def _target_named(self, base: str, suffix: str) -> Path:
        name = base + suffix
        n = 1
        while name in self._used_names:
            n += 1
            name = f"{base}_{n}{suffix}"
        self._used_names.add(name)
        self.staging.mkdir(parents=True, exist_ok=True)
        return self.staging / name

    def _relative(self, path: Path) -> str:
        return super()._relative(self.texture_dir / Path(path).name)


def save_preset(material, name: str, folder: Path, *, overwrite: bool = False, **meta) -> tuple[Path, list[str]]:
    """Write ``material``'s stack (or its unedited preset, exactly) as a user preset.

    Images are copied next to the preset. Returns (path, notes about images that could not be
    saved). PresetError if the name is taken (and not ``overwrite``) or the material is invalid;
    a failed save leaves the previous version of the preset as it was.
    """
    folder = Path(folder)
    slug = library.slugify(name)
    target = folder / f"{slug}.json"
    if target.exists() and not overwrite:
        raise PresetError(f"a user preset named '{slug}' exists (tick Overwrite to replace it)")
    textures = library.texture_folder(folder, slug)
    staging = textures.with_name(f".{textures.name}.new")
    old_textures = textures.with_name(f".{textures.name}.old")
    old_file = target.with_name(f".{target.name}.old")
    for leftover in (staging, old_textures):
        shutil.rmtree(leftover, ignore_errors=True)
    notes: list[str] = []
    was_exact = preset_link.state(material) == preset_link.EXACT
    dropped = preset_link.dropped(material) if was_exact else []
    try:
        images = _PresetImages(folder, textures, staging, notes)
        doc = stack_json(material, images, linked=preset_link.linked_json(images))
    except StackError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise PresetError(str(exc)) from None
    # Swap in the new version, keeping the previous one aside until the new one has been checked.
    if textures.exists():
        textures.rename(old_textures)
    if staging.exists():
        staging.rename(textures)
    if target.exists():
        shutil.copy2(target, old_file)
    try:
        path = library.write(doc, name, folder, overwrite=overwrite, **meta)
        try:
            library.validate(path)
        except BaseException:
            path.unlink(missing_ok=True)
            raise
    except BaseException:
        shutil.rmtree(textures, ignore_errors=True)
        if old_textures.exists():
            old_textures.rename(textures)
        if old_file.exists():
            old_file.replace(target)
        raise
    shutil.rmtree(old_textures, ignore_errors=True)
    old_file.unlink(missing_ok=True)
    library.clear_cache()
    saved = library.read_document(path)
    preset_link.attach(material, name=saved[0], label=saved[1], path=path, doc=saved[2], dropped_fields=dropped)
    material.update_tag()
    return path, notes


# ------------------------------------------------------------------------ operators

class LAMINA_OT_preset_apply(bpy.types.Operator):
    bl_idname = "lamina.preset_apply"
    bl_label = "Apply Material Preset"
    bl_description = "Replace the layer stack of the active material with a preset"
    bl_options = {"REGISTER", "UNDO"}

    name: StringProperty(name="Preset", description="Preset name", options={"SKIP_SAVE"})
    filepath: StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"})

    @classmethod
    def poll(cls, context):
        return getattr(context, "material", None) is not None

    @classmethod
    def description(cls, context, properties):
        for entry in library.entries():
            if entry.name == properties.name or str(entry.path) == properties.filepath:
                return entry.description or entry.label
        return cls.bl_description

    def execute(self, context):
        path = Path(self.filepath) if self.filepath else library.find(self.name)
        if path is None:
            self.report({"ERROR"}, f"Lamina: no preset named '{self.name}'")
            return {"CANCELLED"}
        try:
            label, dropped = apply_preset(context.material, path)
        except PresetError as exc:
            self.report({"ERROR"}, f"Lamina: {exc}")
            return {"CANCELLED"}
        from .viewport_colour import request
        request(context.material, force=True)        # Cycles/EEVEE show its colour (ops/viewport_colour.py)
        if dropped:
            self.report({"WARNING"}, f"Lamina: preset '{label}' applied; {len(dropped)} field(s) cannot be "
                                     f"edited in the stack and render from the preset until you edit it: "
                                     f"{_summary(dropped)}")
        else:
            self.report({"INFO"}, f"Lamina: preset '{label}' applied")
        return {"FINISHED"}


class LAMINA_OT_preset_save(bpy.types.Operator):
    bl_idname = "lamina.preset_save"
    bl_label = "Save Current Stack as Preset"
    bl_description = "Save the active material's layer stack as a preset in your user preset folder"
    bl_options = {"REGISTER", "UNDO"}      # the material is linked to the new preset

    name: StringProperty(name="Name", default="My Material")
    description: StringProperty(name="Description", default="")
    category: StringProperty(name="Category", default="user")
    tags: StringProperty(name="Tags", default="", description="Comma-separated tags")
    overwrite: BoolProperty(name="Overwrite", default=False,
                            description="Replace a user preset of the same name")

    @classmethod
    def poll(cls, context):
        mat = getattr(context, "material", None)
        if mat is None or not len(mat.lamina.layers):
            cls.poll_message_set("The active material has no layer stack")
            return False
        if library.user_dir() is None:
            cls.poll_message_set("User presets need Lamina installed as an extension")
            return False
        return True

    def invoke(self, context, event):
        settings = context.material.lamina
        self.name = settings.preset_label or context.material.name
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        folder = library.user_dir(create=True)
        if folder is None:
            self.report({"ERROR"}, "Lamina: user presets need Lamina installed as an extension")
            return {"CANCELLED"}
        tags = [t.strip() for t in self.tags.split(",") if t.strip()]
        try:
            path, notes = save_preset(context.material, self.name, folder, overwrite=self.overwrite,
                                      label=self.name.strip(), category=self.category.strip() or "user",
                                      description=self.description.strip(), tags=tags)
        except PresetError as exc:
            self.report({"ERROR"}, f"Lamina: {exc}")
            return {"CANCELLED"}
        if notes:
            self.report({"WARNING"}, "Lamina: saved without: " + "; ".join(notes))
        prefs = preferences.get(context)
        if prefs is None or prefs.user_preset_thumbnails:
            thumbnail_jobs.request(path, launch.python_executable(), library.backend_environment(),
                                   on_finished=library.clear_cache)
            self.report({"INFO"}, f"Lamina: saved preset {path}; its thumbnail renders in the background")
        else:
            thumbnail_jobs.cancel(path)
            self.report({"INFO"}, f"Lamina: saved preset {path}")
        return {"FINISHED"}


class LAMINA_OT_preset_delete(bpy.types.Operator):
    bl_idname = "lamina.preset_delete"
    bl_label = "Delete User Preset"
    bl_description = "Delete a preset from your user preset folder (materials using it keep their stack)"
    bl_options = {"REGISTER"}

    name: StringProperty(name="Preset", options={"SKIP_SAVE"})

    def invoke(self, context, event):
        return context.window_manager.invoke_confirm(self, event, title=f"Delete preset '{self.name}'?")

    def execute(self, context):
        folder = library.user_dir()
        if folder is None:
            self.report({"ERROR"}, "Lamina: no user preset folder")
            return {"CANCELLED"}
        thumbnail_jobs.cancel(folder / f"{library.slugify(self.name)}.json")
        try:
            library.delete(self.name, folder)
        except PresetError as exc:
            self.report({"ERROR"}, f"Lamina: {exc}")
            return {"CANCELLED"}
        library.clear_cache()
        self.report({"INFO"}, f"Lamina: deleted preset '{self.name}'")
        return {"FINISHED"}


class LAMINA_OT_preset_detach(bpy.types.Operator):
    bl_idname = "lamina.preset_detach"
    bl_label = "Unlink Preset"
    bl_description = ("Forget the preset this stack came from: export then always writes the stack as "
                      "shown (preset fields the editor cannot show are dropped)")
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        mat = getattr(context, "material", None)
        return mat is not None and bool(mat.lamina.preset_material)

    def execute(self, context):
        preset_link.detach(context.material)
        context.material.update_tag()
        return {"FINISHED"}


# ------------------------------------------------------------------------ menus and browser

def _blocks(entries) -> list[tuple[str, list]]:
    """Shipped presets by category (sorted), then the user's presets."""
    shipped: dict[str, list] = {}
    user = []
    for entry in entries:
        if entry.user:
            user.append(entry)
        else:
            shipped.setdefault(entry.category, []).append(entry)
    blocks = [(cat.capitalize(), sorted(items, key=lambda e: e.label)) for cat, items in sorted(shipped.items())]
    if user:
        blocks.append(("User", sorted(user, key=lambda e: e.label)))
    return blocks


def draw_preset_items(layout, entries) -> None:
    """Category headings with one apply entry per preset (thumbnail icons), in columns."""
    blocks = _blocks(entries)
    total = sum(len(items) + 1 for _, items in blocks)
    columns = max(1, math.ceil(total / MENU_ROWS))
    per_column = math.ceil(total / columns)
    row = layout.row()
    col, used = row.column(), 0
    for title, items in blocks:
        if used and used + len(items) + 1 > per_column:
            col, used = row.column(), 0
        col.label(text=title)
        for entry in items:
            text = entry.label + (" (broken)" if entry.error else "")
            op = col.operator(LAMINA_OT_preset_apply.bl_idname, text=text, **previews.icon_args(entry.thumbnail))
            op.name = entry.name
            op.filepath = str(entry.path)
        used += len(items) + 1


class LAMINA_MT_user_presets_delete(bpy.types.Menu):
    bl_idname = "LAMINA_MT_user_presets_delete"
    bl_label = "Delete User Preset"

    def draw(self, context):
        user = [e for e in library.entries() if e.user]
        if not user:
            self.layout.label(text="No user presets")
        for entry in user:
            self.layout.operator(LAMINA_OT_preset_delete.bl_idname, text=entry.label,
                                 **previews.icon_args(entry.thumbnail)).name = entry.name


class LAMINA_MT_material_presets(bpy.types.Menu):
    bl_idname = "LAMINA_MT_material_presets"
    bl_label = "Material Presets"

    def draw(self, context):
        layout = self.layout
        entries = library.entries()
        if entries:
            draw_preset_items(layout, entries)
        for hook in MENU_HOOKS:
            hook(self, context)
        if not entries and not MENU_HOOKS:
            layout.label(text="No presets installed")
        layout.separator()
        layout.operator(LAMINA_OT_preset_save.bl_idname, icon="ADD")
        layout.menu(LAMINA_MT_user_presets_delete.bl_idname, icon="REMOVE")
        if library.user_dir() is not None:
            layout.label(text=f"User presets: {library.user_dir()}", icon="FILE_FOLDER")


_browser_items: list = []      # Blender keeps no copy of dynamic enum items: hold them here


def browser_items(self, context):
    items = []
    for i, entry in enumerate(library.entries()):
        ident = previews.icon_id(entry.thumbnail)
        items.append((entry.name, entry.label, entry.description, ident or previews.GENERIC_ICON, i))
    _browser_items[:] = items or [("NONE", "No presets", "", "INFO", 0)]
    return _browser_items


CLASSES = (LAMINA_OT_preset_apply, LAMINA_OT_preset_save, LAMINA_OT_preset_delete, LAMINA_OT_preset_detach,
           LAMINA_MT_user_presets_delete, LAMINA_MT_material_presets)

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    previews.register()
    _register_classes()
    bpy.types.WindowManager.lamina_preset_browser = EnumProperty(
        name="Preset", items=browser_items, options={"SKIP_SAVE"},
        description="Material preset (thumbnail: a sphere on a checker floor, rendered by Lamina)")


def unregister():
    thumbnail_jobs.cancel()
    thumbnail_jobs.stop_ticking()
    del bpy.types.WindowManager.lamina_preset_browser
    _unregister_classes()
    previews.unregister()
    _browser_items.clear()
