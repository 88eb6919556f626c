"""Shared panel plumbing: engine check, property-editor placement."""
from __future__ import annotations


class LaminaPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES = {"LAMINA"}

    @classmethod
    def poll(cls, context):
        return getattr(context, "engine", None) in cls.COMPAT_ENGINES


def draw_findings(layout, findings) -> None:
    """Warnings/infos as labels with icons (text wraps badly in Blender: one label per line)."""
    if not findings:
        return
    col = layout.column(align=True)
    for level, message in findings:
        icon = {"ERROR": "CANCEL", "WARNING": "ERROR"}.get(level, "INFO")
        col.label(text=message, icon=icon)
