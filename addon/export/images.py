"""Blender Image data-blocks → texture files the backend can read (docs/materials.md).

External image files are referenced where they are (or copied next to the scene for a portable
export); packed images are written out byte for byte; images that exist only in memory
(generated, painted and unsaved) and derived textures (a roughness map squared into α) are
written as PFM — a trivial float format that OpenImageIO reads as linear data — so no colour
management of Blender's image writer gets in the way.
"""
from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import bpy
import numpy as np

from ..util import srgb_to_linear

_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")


def safe_name(name: str) -> str:
    return _SAFE.sub("_", name).strip("._") or "unnamed"


def colorspace_of(image) -> str:
    """The scene-file ``colorspace`` for an image as Blender interprets it."""
    name = image.colorspace_settings.name
    if name == "sRGB":
        return "sRGB"
    if name in ("Non-Color", "Raw", "Generic Data") or "linear" in name.lower():
        return "linear"
    return "auto"


class ImageExporter:
    """Turns images into paths relative to the scene folder (or absolute), once per image."""

    def __init__(self, directory: Path | None, copy_files: bool, notes: list[str]):
        self.directory = Path(directory) if directory is not None else None
        self.copy_files = copy_files
        self.notes = notes          # unsupported things, collected for the one warning
        self._cache: dict = {}
        self._used_names: set[str] = set()
        # id(texture reference) → (reference, label): where each reference came from (a node, a
        # stack interface), so backend errors about it can name it (names.py).
        self.labels: dict[int, tuple] = {}

    def label(self, tex, text: str):
        """Remember that the texture reference ``tex`` comes from ``text``; returns ``tex``."""
        if isinstance(tex, dict):
            self.labels[id(tex)] = (tex, text)
        return tex

    # -- public

    def texture(self, image, *, scale=None, squared: bool = False, channel: int | None = None) -> dict | None:
        """A texture reference ``{"texture": ..., "colorspace": ..., "scale": ...}`` or None."""
        if image is None:
            return None
        key = (image.as_pointer() if hasattr(image, "as_pointer") else id(image), squared)
        if key not in self._cache:
            self._cache[key] = self._export(image, squared)
        entry = self._cache[key]
        if entry is None:
            return None
        path, colorspace = entry
        tex = {"texture": path, "colorspace": colorspace}
        if scale is not None:
            tex["scale"] = scale
        if channel is not None:
            tex["channel"] = channel
        return tex

    def forget(self, image) -> None:
        """Export ``image`` again when next asked (it was edited): a viewport session then gets
        it under a new file name (generated and painted images) or reads the file again."""
        pointers = {image.as_pointer()}
        original = getattr(image, "original", None)
        if original is not None:
            pointers.add(original.as_pointer())
        for key in [k for k in self._cache if k[0] in pointers]:
            del self._cache[key]

    def file(self, source: Path) -> str:
        """A texture path for an image file on disk (a preset's texture): copied next to the
        scene for a portable export, else referenced where it is (absolute)."""
        source = Path(source)
        if not (self.copy_files and self.directory is not None and source.is_file()):
            return str(source)
        key = ("file", str(source.resolve()))
        if key not in self._cache:
            target = self._target_named(safe_name(source.stem), source.suffix)
            shutil.copyfile(source, target)
            self._cache[key] = self._relative(target)
        return self._cache[key]

    # -- internals

    def _target(self, image, suffix: str) -> Path:
        # The file's own name where there is one ("wood.png", not the data-block's "wood.png.001").
        source = Path(bpy.path.basename(image.filepath)) if image.filepath else Path(image.name)
        return self._target_named(safe_name(source.stem or Path(image.name).stem), suffix)

    def _target_named(self, base: str, suffix: str) -> Path:
        name = base + suffix
        n = 1
        while name in self._used_names:
            n += 1
            name = f"{base}_{n}{suffix}"
        self._used_names.add(name)
        folder = self.directory / "textures"
        folder.mkdir(parents=True, exist_ok=True)
        return folder / name

    def _relative(self, path: Path) -> str:
        try:
            return Path(os.path.relpath(path, self.directory)).as_posix()
        except ValueError:          # another drive on Windows
            return str(path)

    def _export(self, image, squared: bool):
        if image.source in ("MOVIE", "SEQUENCE", "TILED", "VIEWER"):
            self.notes.append(f"image '{image.name}' ({image.source.lower()} images are not supported)")
            return None
        if squared or image.source == "GENERATED" or image.is_dirty:
            if self.directory is None:
                return ("<in-memory>", "linear")
            return self._write_pfm(image, squared)
        if image.packed_file is not None:
            if self.directory is None:
                return ("<packed>", colorspace_of(image))
            ext = Path(image.filepath).suffix or "." + image.file_format.lower()
            target = self._target(image, ext)
            target.write_bytes(bytes(image.packed_file.data))
            return (self._relative(target), colorspace_of(image))
        source = Path(bpy.path.abspath(image.filepath, library=image.library))
        if not source.is_file():
            # The backend reports a missing file with its path; keep the reference so it does.
            return (str(source), colorspace_of(image))
        if self.copy_files and self.directory is not None:
            target = self._target(image, source.suffix)
            shutil.copyfile(source, target)
            return (self._relative(target), colorspace_of(image))
        return (str(source), colorspace_of(image))

    def _write_pfm(self, image, squared: bool):
        w, h = image.size
        if w == 0 or h == 0:
            self.notes.append(f"image '{image.name}' (no pixels: the file could not be loaded)")
            return None
        channels = image.channels
        px = np.empty(w * h * channels, np.float32)
        image.pixels.foreach_get(px)
        px = px.reshape(h, w, channels)        # row 0 = bottom, as PFM stores it
        rgb = px[:, :, :3] if channels >= 3 else np.repeat(px[:, :, :1], 3, axis=2)
        # Byte images hold encoded values; float buffers are already scene-linear.
        if not image.is_float and colorspace_of(image) == "sRGB":
            rgb = srgb_to_linear(rgb)
        if squared:                            # Blender roughness r → microfacet α = r²
            rgb = rgb * rgb
        target = self._target(image, ".pfm")
        write_pfm(target, rgb)
        return (self._relative(target), "linear")


def write_pfm(path: Path, rgb_bottom_up: np.ndarray) -> None:
    """Colour PFM: header, then little-endian float32 rows from the bottom row up."""
    h, w, _ = rgb_bottom_up.shape
    with open(path, "wb") as f:
        f.write(f"PF\n{w} {h}\n-1.0\n".encode("ascii"))
        f.write(np.ascontiguousarray(rgb_bottom_up, dtype="<f4").tobytes())
