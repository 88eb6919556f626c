"""Lamina Blender extension entry point (id "lamina"); everything lives in ``addon/``.

The extension is imported by Blender as ``bl_ext.<repository>.lamina``: only relative imports are
used. The renderer (``backend/``) runs in a child process (see addon/engine); the only backend
module imported into Blender is the bpy-free preset file handling (``backend/presets.py``, as a
sibling package through a relative import, for addon/presets).
"""
from . import addon


def register():
    addon.register()


def unregister():
    addon.unregister()
