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


def _excluded(name: str) -> bool:
    return name in EXCLUDE or name.startswith(EXCLUDE_PREFIXES)


def panels_to_extend():
    panels = [p for p in bpy.types.Panel.__subclasses__() if getattr(p, "COMPAT_ENGINES", None) is not None]
    # Subclassed panels share their parent's set (NODE_DATA_PT_light uses DATA_PT_light's):
    # a set that belongs to an excluded panel is never extended.
    blocked = {id(p.COMPAT_ENGINES) for p in panels if _excluded(p.__name__)}
    return [p for p in panels if id(p.COMPAT_ENGINES) not in blocked
            and (p.__name__ in EXTRA or "BLENDER_RENDER" in p.COMPAT_ENGINES)]


def register():
    for panel in panels_to_extend():
        if ENGINE not in panel.COMPAT_ENGINES:
            panel.COMPAT_ENGINES.add(ENGINE)
            _added.append(panel)


def unregister():
    for panel in _added:
        panel.COMPAT_ENGINES.discard(ENGINE)
    _added.clear()
