"""Depsgraph → Lamina scene description (docs/scene-format.md)."""
from .scene import export_scene, ExportResult  # noqa: F401
