"""Backend arrays → Blender render-result passes (row 0 of ``rect`` is the bottom row)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

ALBEDO_PASS = "Denoising Albedo"
NORMAL_PASS = "Denoising Normal"


def load_npy(path: Path):
    """The array in ``path``, or None if it is missing or being replaced (atomic renames)."""
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError):
        return None


def region(image: np.ndarray, rect, full_height: int) -> np.ndarray:
    """Cut Blender's border region (x, y-from-bottom, w, h) out of a top-row-first image and
    return it bottom-row-first, as ``rect.foreach_set`` wants it."""
    x, y, w, h = rect
    top = full_height - (y + h)
    return np.ascontiguousarray(image[top:top + h, x:x + w][::-1], dtype=np.float32)


def pass_npy_path(partial: Path, pass_name: str) -> Path:
    """Where the backend writes the final data pass ``pass_name`` (Blender's name, e.g. 'Object
    Index') next to the partial result (docs/cli.md, add-on protocol)."""
    slug = pass_name.lower().replace(" ", "-")
    return partial.with_suffix(f".pass-{slug}.npy")


def fill_passes(result, combined: np.ndarray, aovs: np.ndarray | None, rect, full_height: int,
                data_passes: dict | None = None) -> None:
    """Write combined RGBA (+ albedo, normal, and ``data_passes``: Blender pass name → image)
    into the first layer of a RenderResult.

    Passes that Lamina does not produce (enabled by the user for other engines) are zero."""
    layer = result.layers[0]
    w, h = rect[2], rect[3]
    for render_pass in layer.passes:
        channels = render_pass.channels
        if render_pass.name == "Combined":
            data = region(combined[:, :, :4], rect, full_height)
        elif render_pass.name == ALBEDO_PASS and aovs is not None:
            data = region(aovs[:, :, 0:3], rect, full_height)
        elif render_pass.name == NORMAL_PASS and aovs is not None:
            data = region(aovs[:, :, 3:6], rect, full_height)
        elif data_passes and render_pass.name in data_passes:
            data = region(data_passes[render_pass.name], rect, full_height)
        else:
            data = np.zeros((h, w, channels), np.float32)
        if data.shape[2] != channels:
            fixed = np.zeros((h, w, channels), np.float32)
            c = min(channels, data.shape[2])
            fixed[:, :, :c] = data[:, :, :c]
            data = fixed
        render_pass.rect.foreach_set(data.ravel())
