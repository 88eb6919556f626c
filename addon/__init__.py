"""The Blender side of Lamina: properties, UI, operators, scene export and the render engine.

Import ranks (lower never imports higher): ``util``/``stack_check``/``constants`` (no bpy) <
``props`` < ``presets.library`` < ``export`` < ``ops``/``presets.convert`` < ``engine`` < ``ui``. Modules register in that order and
unregister in reverse. No module touches ``gpu``, keymaps or the network at register time, so
``blender -b`` works.
"""
from __future__ import annotations

import importlib

_MODULES = (
    "preferences",
    "props.layer",
    "props.material",
    "props.light",
    "props.scene",
    "ops.stack",
    "ops.presets",
    "ops.export",
    "ops.bake",
    "ops.viewport_colour",
    "engine.engine",
    "engine.kernel_warmup",
    "engine.viewport",
    "ui.compat",
    "ui.material",
    "ui.light",
    "ui.world",
    "ui.render",
)


def _modules():
    return [importlib.import_module(f".{name}", __name__) for name in _MODULES]


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
