"""File > Export > Lamina Scene: write the scene description for the command line or a farm."""
from __future__ import annotations

from pathlib import Path

import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper

from ..export import export_scene
from ..export.scene import ExportError, warning_text
from .bake import bake_materials, scene_materials


class LAMINA_OT_export_scene(bpy.types.Operator, ExportHelper):
    bl_idname = "lamina.export_scene"
    bl_label = "Export Lamina Scene"
    bl_description = ("Write the scene as a Lamina scene description (JSON + meshes) that "
                      "`python -m backend render` renders without Blender")
    bl_options = {"REGISTER"}

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    copy_textures: BoolProperty(name="Copy Textures", default=True,
                                description="Copy image files next to the scene (portable); "
                                            "otherwise reference them where they are")
    animation: BoolProperty(name="Animation", default=False,
                            description="Export every frame of the frame range as NAME_####.json")
    bake_procedurals: BoolProperty(
        name="Bake Procedural Textures", default=True,
        description="Before writing, bake the procedural textures and node chains the export cannot "
                    "translate into images (those not baked yet, or changed since), as the material "
                    "panel's Bake Procedural Textures does; once, at the current frame")
    bake_resolution: IntProperty(name="Bake Resolution", default=1024, min=16, max=8192,
                                 description="Width and height of each baked image, in pixels")

    def execute(self, context):
        path = Path(self.filepath)
        scene = context.scene
        frames = range(scene.frame_start, scene.frame_end + 1, max(1, scene.frame_step)) \
            if self.animation else [scene.frame_current]
        original_frame = scene.frame_current
        notes: list[str] = []
        triangles = 0
        if self.bake_procedurals:
            # Blender bakes only outside a render, so the export (not F12) can bake by itself.
            done, problems = bake_materials(context, scene_materials(scene), self.bake_resolution,
                                            only_missing=True)
            notes.extend(f"bake: {p}" for p in problems)
            if done:
                self.report({"INFO"}, f"Lamina: baked {done} procedural input(s) at {self.bake_resolution}²")
        try:
            for frame in frames:
                if self.animation:
                    scene.frame_set(frame)
                    filename = f"{path.stem}_{frame:04d}.json"
                    meshes = f"{path.stem}_{frame:04d}_meshes"
                else:
                    filename = path.name
                    meshes = f"{path.stem}_meshes"
                depsgraph = context.evaluated_depsgraph_get()
                seed = frame if scene.lamina.use_animated_seed else 0
                result = export_scene(depsgraph, path.parent, copy_textures=self.copy_textures,
                                      seed_offset=seed, filename=filename, mesh_folder=meshes,
                                      frame_set=lambda f, sub: scene.frame_set(f, subframe=sub))
                notes.extend(result.notes)
                triangles = result.stats["triangles"]
        except ExportError as exc:
            self.report({"ERROR"}, f"Lamina: {exc}")
            return {"CANCELLED"}
        finally:
            if self.animation:
                scene.frame_set(original_frame)
        if notes:
            self.report({"WARNING"}, warning_text(notes))
        self.report({"INFO"}, f"Lamina: exported {len(frames)} frame(s), {triangles} triangles → {path.parent}")
        return {"FINISHED"}


def menu_export(self, context):
    self.layout.operator(LAMINA_OT_export_scene.bl_idname, text="Lamina Scene (.json)")


def register():
    bpy.utils.register_class(LAMINA_OT_export_scene)
    bpy.types.TOPBAR_MT_file_export.append(menu_export)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    bpy.utils.unregister_class(LAMINA_OT_export_scene)
