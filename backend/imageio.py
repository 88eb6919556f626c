"""Writing results: EXR with passes (OpenImageIO), PNG/JPEG previews, raw .npy for the add-on.

Every writer goes to a temporary file in the target folder and renames it into place
(``os.replace`` is atomic on POSIX and Windows), so an interrupted render never leaves a corrupt
or half-written output.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import LaminaError
from .textures import linear_to_srgb


def _default_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def _atomic_target(path: Path, suffix: str):
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=suffix, dir=path.parent)
    os.close(fd)
    # mkstemp creates 0600 files; outputs get the usual permissions once renamed into place.
    os.chmod(tmp, _default_mode())
    return Path(tmp)


def write_exr(path: str | Path, layers: dict[str, np.ndarray], half: bool = False) -> None:
    """layers: channel-group name → (H, W, C) float array, in order. '' = the main RGBA group.

    Channel names: the main group gets R, G, B, A; others '<name>.<X>' with X from the name's
    convention (RGB for colours, XYZ for 'normal', Y for single channels).
    """
    import OpenImageIO as oiio

    path = Path(path)
    names, planes = [], []
    for group, image in layers.items():
        image = np.asarray(image, dtype=np.float32)
        if image.ndim == 2:
            image = image[:, :, None]
        c = image.shape[2]
        if group == "":
            letters = "RGBA"[:c]
        elif group == "normal":
            letters = "XYZ"[:c]
        elif c == 1:
            letters = "Y"
        else:
            letters = "RGBA"[:c]
        names += [f"{group}.{ch}" if group else ch for ch in letters]
        planes.append(image)
    data = np.ascontiguousarray(np.concatenate(planes, axis=2))
    h, w, c = data.shape
    spec = oiio.ImageSpec(w, h, c, oiio.HALF if half else oiio.FLOAT)
    spec.channelnames = tuple(names)
    if "A" in names:
        spec.alpha_channel = names.index("A")
    spec.attribute("compression", "zip")
    spec.attribute("Software", "Lamina")
    tmp = _atomic_target(path, ".exr")
    try:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise LaminaError(f"cannot write {path}: {oiio.geterror()}")
        ok = out.write_image(data)
        out.close()
        if not ok:
            raise LaminaError(f"cannot write {path}: {out.geterror()}")
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_preview(path: str | Path, rgb: np.ndarray, exposure: float = 0.0) -> None:
    """Display-referred 8-bit preview (sRGB transfer, clipped) as PNG or JPEG."""
    import OpenImageIO as oiio

    path = Path(path)
    img = np.asarray(rgb, dtype=np.float64)[:, :, :3] * (2.0 ** exposure)
    img = np.where(np.isfinite(img), img, 0.0)
    data = np.clip(np.round(linear_to_srgb(img) * 255.0), 0, 255).astype(np.uint8)
    h, w, _ = data.shape
    spec = oiio.ImageSpec(w, h, 3, oiio.UINT8)
    tmp = _atomic_target(path, path.suffix or ".png")
    try:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise LaminaError(f"cannot write {path}: {oiio.geterror()}")
        ok = out.write_image(np.ascontiguousarray(data))
        out.close()
        if not ok:
            raise LaminaError(f"cannot write {path}: {out.geterror()}")
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_npy(path: str | Path, array: np.ndarray) -> None:
    path = Path(path)
    tmp = _atomic_target(path, ".npy")
    try:
        with open(tmp, "wb") as f:
            np.save(f, np.ascontiguousarray(array, dtype=np.float32))
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def read_exr(path: str | Path) -> tuple[np.ndarray, list[str]]:
    """(H, W, C) float32 pixels and channel names (tests, tools)."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise LaminaError(f"cannot read {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        names = list(spec.channelnames)
    finally:
        inp.close()
    return np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels), names
