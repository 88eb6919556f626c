"""Render › Denoise for Lamina renders, with the denoiser Blender ships: Intel Open Image Denoise
inside Cycles, through Cycles' standalone file denoiser (``_cycles.denoise``, the function behind
*Render › Denoise Animation*). It works the same in the UI and under ``blender -b`` in every
Blender from 4.2 on, needs no GPU, and adds no wheel to the extension.

That denoiser reads a multilayer EXR laid out as Cycles writes one with *Denoising Data* on: a
render layer with the passes Noisy Image, Denoising Albedo, Denoising Normal, Denoising Depth and
Vector, and the layer's sample count in the header (``cycles.<layer>.samples``); it writes the
denoised image into that layer's Combined. This module writes such a file from the renderer's
combined image and its albedo and normal (the first-hit features OIDN's RT filter expects), runs
the denoiser and reads the result back. No rendering maths here: the denoising is OIDN's.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

NOISY_PASS = "Noisy Image"     # Cycles' name for the image before denoising
LAYER = "Lamina"               # the file's render layer (any name: the denoiser takes the first with the passes)


class DenoiseError(Exception):
    """Denoising could not run; the message says why (the render keeps its noisy image)."""


def _channels(combined: np.ndarray, aovs: np.ndarray) -> tuple[list[str], np.ndarray]:
    h, w = combined.shape[:2]
    rgba = np.ascontiguousarray(combined[:, :, :4], np.float32)
    planes = [("Combined", "RGBA", rgba), (NOISY_PASS, "RGBA", rgba),
              ("Denoising Albedo", "RGB", np.clip(aovs[:, :, 0:3], 0.0, 1.0)),
              ("Denoising Normal", "XYZ", np.clip(aovs[:, :, 3:6], -1.0, 1.0)),
              # Depth and Vector only make the layer one the denoiser accepts (its temporal mode
              # reads them); one frame is denoised, so they carry nothing.
              ("Denoising Depth", "Z", np.ones((h, w, 1), np.float32)),
              ("Vector", "XYZW", np.zeros((h, w, 4), np.float32))]
    names, data = [], []
    for name, letters, image in planes:
        for i, letter in enumerate(letters):
            names.append(f"{LAYER}.{name}.{letter}")
            data.append(image[:, :, i])
    pixels = np.nan_to_num(np.stack(data, axis=2).astype(np.float32), nan=0.0, posinf=3.0e38, neginf=0.0)
    return names, pixels


def denoise_image(combined: np.ndarray, aovs: np.ndarray, samples: int, folder: Path, scene,
                  view_layer, preferences) -> np.ndarray:
    """The denoised RGBA image (alpha kept) of ``combined`` (H, W, 4, top row first) with
    ``aovs`` (H, W, 6: albedo, normal). ``scene``/``view_layer``/``preferences`` are Blender's:
    the denoiser reads its settings (Cycles' denoiser type, prefilter, quality) from them."""
    try:
        import OpenImageIO as oiio
        import _cycles
    except ImportError as exc:
        raise DenoiseError(f"this Blender has no {exc.name} module") from None
    if combined.ndim != 3 or aovs is None or aovs.shape[:2] != combined.shape[:2]:
        raise DenoiseError("the renderer wrote no albedo and normal")
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DenoiseError(f"cannot create {folder}: {exc.strerror or exc}") from None
    source, target = folder / "denoise-in.exr", folder / "denoise-out.exr"
    names, pixels = _channels(combined, aovs)
    h, w = combined.shape[:2]
    spec = oiio.ImageSpec(w, h, len(names), oiio.FLOAT)
    spec.channelnames = names
    spec.attribute(f"cycles.{LAYER}.samples", str(max(int(samples), 1)))
    out = oiio.ImageOutput.create(str(source))
    if out is None or not out.open(str(source), spec) or not out.write_image(pixels):
        raise DenoiseError(f"cannot write {source}: {oiio.geterror()}")
    out.close()
    try:
        _cycles.denoise(preferences.as_pointer(), scene.as_pointer(), view_layer.as_pointer(),
                        input=[str(source)], output=[str(target)])
    except Exception as exc:  # noqa: BLE001 - Cycles raises RuntimeError with its own words
        raise DenoiseError(str(exc).strip() or type(exc).__name__) from None
    result = oiio.ImageBuf(str(target))
    if result.has_error:
        raise DenoiseError(f"the denoiser wrote no image ({result.geterror()})")
    read_names = list(result.spec().channelnames)
    try:
        index = [read_names.index(f"{LAYER}.Combined.{c}") for c in "RGB"]
    except ValueError:
        raise DenoiseError("the denoiser's output has no Combined pass") from None
    data = np.asarray(result.get_pixels(oiio.FLOAT)).reshape(h, w, len(read_names))
    denoised = np.array(combined[:, :, :4], np.float32)
    denoised[:, :, :3] = data[:, :, index]
    return denoised
