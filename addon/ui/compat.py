"""Show Blender's own panels (camera, output, colour management, ...) for the Lamina engine.

Panels declare the engines they support in ``COMPAT_ENGINES``; like Cycles, we join every panel
that supports the generic 'BLENDER_RENDER' list except those Lamina replaces or cannot honour,
plus a few EEVEE panels whose content applies unchanged (camera depth of field, the material slot
list and the preview).
"""
from __future__ import annotations

import bpy

ENGINE = "LAMINA"

EXCLUDE = {
    "DATA_PT_light",                 # replaced by LAMINA_PT_light
    "MATERIAL_PT_freestyle_line",
    "VIEWLAYER_PT_layer_passes",
}
EXCLUDE_PREFIXES = ("RENDER_PT_freestyle", "VIEWLAYER_PT_freestyle", "RENDER_PT_gpencil",
                    "RENDER_PT_grease_pencil", "DATA_PT_lightprobe", "RENDER_PT_simplify_greasepencil")

EXTRA = {
    "DATA_PT_camera_dof",
    "DATA_PT_camera_dof_aperture",
    "EEVEE_MATERIAL_PT_context_material",
    "MATERIAL_PT_preview",
}

_added: list = []


def panels_to_extend():
    out = []
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is None:
            continue
        name = panel.__name__
        if name in EXTRA or ("BLENDER_RENDER" in engines and name not in EXCLUDE
                             and not name.startswith(EXCLUDE_PREFIXES)):
            out.append(panel)
    return out


def register():
    for panel in panels_to_extend():
        if ENGINE not in panel.COMPAT_ENGINES:
            panel.COMPAT_ENGINES.add(ENGINE)
            _added.append(panel)


def unregister():
    for panel in _added:
        panel.COMPAT_ENGINES.discard(ENGINE)
    _added.clear()
