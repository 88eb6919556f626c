"""Add-on preferences (``bl_idname = __package__`` of the extension)."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty

# The top-level package: "bl_ext.<repo>.lamina" when installed, "lamina" in development.
ADDON_ID = __package__.rpartition(".")[0]


def _thumbnails_toggled(self, context):
    if not self.user_preset_thumbnails:
        from .presets import thumbnail_jobs      # lazy: presets rank above preferences
        thumbnail_jobs.cancel()


#: Rows that modules above this one add to the Preferences (they register after it).
EXTRA_DRAW: list = []

class LaminaPreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_ID

    python_executable: StringProperty(
        name="Backend Python", subtype='FILE_PATH', default="",
        description="Python interpreter for the renderer process; empty = Blender's own Python "
                    "(recommended: it has numpy, and the bundled embreex is installed for it)")
    keep_files: BoolProperty(
        name="Keep Render Files", default=False,
        description="Keep the exported scene and the backend output in the temporary folder "
                    "(for bug reports and for rendering again with the command line)")

    # Material previews render Blender's own preview scene, not the user's: a global setting.
    preview_samples: IntProperty(
        name="Preview Samples", default=16, min=1, soft_max=256,
        description="Samples per pixel of material, light and world preview thumbnails")

    viewport_prestart: BoolProperty(
        name="Pre-start Viewport Renderer", default=True,
        description="While a scene renders with Lamina, keep one idle renderer process ready (it loads "
                    "its libraries and compiled kernels in advance, and uses no CPU while it waits), so "
                    "Rendered shading shows its first image within about a second")

    keep_renderer_warm: BoolProperty(
        name="Keep Renderer Warm", default=True,
        description="Render F12, animation frames and material previews in renderer processes that "
                    "stay loaded between renders (one for final renders, one for previews; idle they "
                    "use no CPU and about 200 MB of memory each), so a render does not start Python and "
                    "load the compiled kernels each time. Off: a new process for every render")

    user_preset_thumbnails: BoolProperty(
        name="Thumbnails for Saved Presets", default=True, update=_thumbnails_toggled,
        description="Render a thumbnail for each preset you save, in the background (one renderer "
                    "process, tens of seconds per preset; the same stage as the shipped thumbnails)")

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "python_executable")
        layout.prop(self, "keep_files")
        layout.prop(self, "preview_samples")
        layout.prop(self, "viewport_prestart")
        layout.prop(self, "keep_renderer_warm")
        layout.prop(self, "user_preset_thumbnails")
        for draw in EXTRA_DRAW:                 # higher modules' rows (engine/kernel_warmup.py)
            draw(layout)


def get(context=None):
    """The preferences, or None when the add-on is not registered under ADDON_ID (tests)."""
    context = context or bpy.context
    addon = context.preferences.addons.get(ADDON_ID)
    return addon.preferences if addon else None


def register():
    bpy.utils.register_class(LaminaPreferences)


def unregister():
    bpy.utils.unregister_class(LaminaPreferences)
