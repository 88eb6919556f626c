"""User-facing errors. The CLI prints these as one line and exits non-zero (never a traceback)."""
from __future__ import annotations


class LaminaError(Exception):
    """An error caused by user input (a scene, a material, an IES file, a command line)."""


class SceneError(LaminaError):
    """A scene/material file is invalid. ``where`` is the file, ``path`` the field path."""

    def __init__(self, where: str, path: str, message: str):
        self.where, self.path, self.message = where, path, message
        location = f"{where}: " if where else ""
        field = f"{path}: " if path else ""
        super().__init__(f"{location}{field}{message}")


#: What a render that ran out of memory says (the ``render`` command and the render server).
OUT_OF_MEMORY = ("not enough memory for this scene or image (try a smaller film, fewer workers, "
                 "or a machine with more memory)")
