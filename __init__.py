"""Lamina Blender extension entry point (id "lamina"); everything lives in ``addon/``.

The extension is imported by Blender as ``bl_ext.<repository>.lamina``: only relative imports are
used, and ``backend/`` is never imported here (it runs in a child process, see addon/engine).
"""
from . import addon


def register():
    addon.register()


def unregister():
    addon.unregister()
