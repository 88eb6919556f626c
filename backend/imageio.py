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
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise LaminaError(f"cannot write {path}: cannot create the folder {path.parent} "
                          f"({exc.strerror or exc})") from exc
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=suffix, dir=path.parent)
    except OSError as exc:
        raise LaminaError(f"cannot write {path}: {exc.strerror or exc}") from exc
    os.close(fd)
    # mkstemp creates 0600 files; outputs get the usual permissions once renamed into place.
    os.chmod(tmp, _default_mode())
    return Path(tmp)


def check_writable(path: str | Path, what: str = "output") -> None:
    """Fail now, not after a long render, if ``path`` cannot be written: its folder is created
    (as the writers would) and a scratch file is made and removed there; its extension must name
    a format OpenImageIO writes (.npy is written by NumPy). Raises LaminaError."""
    path = Path(path)
    if path.is_dir():
        raise LaminaError(f"the {what} {path} is a folder; give a file name")
    tmp = _atomic_target(path, path.suffix or ".tmp")
    tmp.unlink()
    if path.suffix.lower() != ".npy":
        import OpenImageIO as oiio
        if oiio.ImageOutput.create(str(path)) is None:
            oiio.geterror()                     # clear it: OIIO prints unread errors at exit
            raise LaminaError(f"the {what} {path}: OpenImageIO cannot write '{path.suffix}' files")


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
