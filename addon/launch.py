"""How the renderer child processes are launched from Blender: which Python runs them, the
environment that tells them where the user's presets and the compiled-kernel cache live, and
whether their files are kept. Shared by final renders (engine/engine.py), Rendered shading
(engine/viewport.py) and the preset library's child processes (presets/library.py)."""
from __future__ import annotations

import os
import sys

import bpy

from . import preferences


def python_executable() -> str:
    prefs = preferences.get()
    if prefs is not None and prefs.python_executable:
        return bpy.path.abspath(prefs.python_executable)
    return sys.executable


def keep_files() -> bool:
    prefs = preferences.get()
    return bool(prefs and prefs.keep_files)


def keep_renderer_warm() -> bool:
    """Preferences › Keep Renderer Warm (on by default; on when not registered, as in tests)."""
    prefs = preferences.get()
    return bool(prefs.keep_renderer_warm) if prefs is not None else True


def user_environment() -> dict:
    """Where the backend finds user presets and caches its compiled kernels: the extension's user
    folder (never the install folder, which an update replaces and may be read-only), unless
    LAMINA_KERNEL_CACHE is set in Blender's own environment."""
    env = {}
    try:
        env["LAMINA_PRESET_PATH"] = bpy.utils.extension_path_user(preferences.ADDON_ID, path="presets",
                                                                  create=False)
        if not os.environ.get("LAMINA_KERNEL_CACHE"):     # set in Blender's environment, it wins
            env["LAMINA_KERNEL_CACHE"] = bpy.utils.extension_path_user(preferences.ADDON_ID, path="kernels",
                                                                       create=True)
    except (ValueError, RuntimeError, TypeError):   # not installed as an extension (development)
        pass
    return env
