"""Writing results: EXR with passes (OpenImageIO), PNG/JPEG previews, raw .npy for the add-on.

Every writer goes to a temporary file in the target folder and renames it into place
(``os.replace`` is atomic on POSIX and Windows), so an interrupted render never leaves a corrupt
or half-written output. Temporary files are hidden and named
``.<name>.lamina-tmp-<host>-<pid>-<random><ext>``; one left behind by a process that was killed
mid-write (SIGKILL, power loss) is removed by the next write to that folder from the same host
once its process is gone (``remove_stale_temp_files``).

Pixel values are written finite: NaN becomes 0 and values beyond the format's range (float32:
±3.4e38; half: ±65504) are clamped to it. The writers return how many values they changed, so
the caller can say so.
"""
from __future__ import annotations

import os
import re
import socket
import tempfile
from pathlib import Path

import numpy as np

from .errors import LaminaError
from .textures import linear_to_srgb

TEMP_TAG = ".lamina-tmp-"
HALF_MAX = 65504.0
FLOAT_MAX = float(np.finfo(np.float32).max)


def _default_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def _host() -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", socket.gethostname() or "host")[:40] or "host"


def _temp_prefix(path: Path) -> str:
    return f".{path.stem[:100]}{TEMP_TAG}{_host()}-{os.getpid()}-"


_TEMP_RE = re.compile(r"^\..*" + re.escape(TEMP_TAG) + r"(?P<host>[A-Za-z0-9_]+)-(?P<pid>\d+)-[^/]*$")


def _process_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    if os.name == "nt":  # os.kill(pid, 0) would *terminate* the process on Windows
        import ctypes
        kernel32 = ctypes.windll.kernel32
        handle = kernel32.OpenProcess(0x1000, False, pid)   # PROCESS_QUERY_LIMITED_INFORMATION
        if not handle:
            return kernel32.GetLastError() == 5             # access denied: it exists
        code = ctypes.c_ulong()
        ok = kernel32.GetExitCodeProcess(handle, ctypes.byref(code))
        kernel32.CloseHandle(handle)
        return bool(ok) and code.value == 259               # STILL_ACTIVE
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def remove_stale_temp_files(folder: Path) -> list[Path]:
    """Remove this host's temporary files in ``folder`` whose writing process no longer runs
    (a write interrupted by SIGKILL or a crash). Files of other hosts (a shared network folder)
    and of running processes are left alone. Returns the removed paths; never raises."""
    removed = []
    host = _host()
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return removed
    for entry in entries:
        m = _TEMP_RE.match(entry.name)
        if not m or m.group("host") != host:
            continue
        try:
            if _process_alive(int(m.group("pid"))):
                continue
            entry.unlink()
            removed.append(entry)
        except (OSError, ValueError, OverflowError):
            continue
    return removed


def _atomic_target(path: Path, suffix: str):
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise LaminaError(f"cannot write {path}: cannot create the folder {path.parent} "
                          f"({exc.strerror or exc})") from exc
    remove_stale_temp_files(path.parent)
    try:
        fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path), suffix=suffix, dir=path.parent)
    except OSError as exc:
        raise LaminaError(f"cannot write {path}: {exc.strerror or exc}") from exc
    os.close(fd)
    # mkstemp creates 0600 files; outputs get the usual permissions once renamed into place.
    os.chmod(tmp, _default_mode())
    return Path(tmp)


def finite_values(data: np.ndarray, limit: float) -> tuple[np.ndarray, int]:
    """``data`` with NaN → 0 and everything clamped to ±``limit``; and how many values changed."""
    bad = ~(np.abs(data) <= limit)            # NaN, ±Inf and out-of-range values
    count = int(np.count_nonzero(bad))
    if count:
        data = np.where(np.isnan(data), 0.0, np.clip(data, -limit, limit)).astype(data.dtype)
    return data, count


def check_writable(path: str | Path, what: str = "output") -> None:
    """Fail now, not after a long render, if ``path`` cannot be written: its folder is created
    (as the writers would) and a scratch file is made and removed there; its extension must name
    a format OpenImageIO writes (.npy is written by NumPy). Raises LaminaError."""
    path = Path(path)
    try:
        if path.is_dir():
            raise LaminaError(f"the {what} {path} is a folder; give a file name")
    except (OSError, ValueError) as exc:
        raise LaminaError(f"cannot write the {what} {str(path)[:200]}: "
                          f"{getattr(exc, 'strerror', None) or exc}") from None
    tmp = _atomic_target(path, path.suffix or ".tmp")
    tmp.unlink()
    if path.suffix.lower() != ".npy":
        import OpenImageIO as oiio
        if oiio.ImageOutput.create(str(path)) is None:
            oiio.geterror()                     # clear it: OIIO prints unread errors at exit
            raise LaminaError(f"the {what} {path}: OpenImageIO cannot write '{path.suffix}' files")


def write_exr(path: str | Path, layers: dict[str, np.ndarray], half: bool = False) -> int:
    """layers: channel-group name → (H, W, C) float array, in order. '' = the main RGBA group.

    Channel names: the main group gets R, G, B, A; the data passes their Blender channel names
    (backend/passes.py: 'Depth' → Z, 'UV' → U, V, A); others '<name>.<X>' with X from the name's
    convention (RGB for colours, XYZ for 'normal', Y for single channels). Returns the number of
    values that were not finite or beyond the format's range (written as 0 / clamped).
    """
    import OpenImageIO as oiio

    from .passes import channel_letters
    letters = channel_letters()

    path = Path(path)
    names, planes = [], []
    for group, image in layers.items():
        with np.errstate(over="ignore", invalid="ignore"):   # out-of-range values: see below
            image = np.asarray(image, dtype=np.float32)
        if image.ndim == 2:
            image = image[:, :, None]
        c = image.shape[2]
        if group in letters:
            letters_of = letters[group][:c]
        elif group == "":
            letters_of = "RGBA"[:c]
        elif group == "normal":
            letters_of = "XYZ"[:c]
        elif c == 1:
            letters_of = "Y"
        else:
            letters_of = "RGBA"[:c]
        names += [f"{group}.{ch}" if group else ch for ch in letters_of]
        planes.append(image)
    data = np.ascontiguousarray(np.concatenate(planes, axis=2))
    data, changed = finite_values(data, HALF_MAX if half else FLOAT_MAX)
    h, w, c = data.shape
    spec = oiio.ImageSpec(w, h, c, oiio.HALF if half else oiio.FLOAT)
    spec.channelnames = tuple(names)
    if "A" in names:
        spec.alpha_channel = names.index("A")
    spec.attribute("compression", "zip")
    spec.attribute("Software", "Lamina")
    _write_atomically(path, ".exr", spec, data)
    return changed


def _write_atomically(path: Path, suffix: str, spec, data: np.ndarray) -> None:
    """Write an image to a temporary name beside ``path`` and rename it over ``path``: a reader
    never sees half a file, and a failed write leaves what was there."""
    import OpenImageIO as oiio
    tmp = _atomic_target(path, suffix)
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
    _write_atomically(path, path.suffix or ".png", spec, np.ascontiguousarray(data))


def write_npy(path: str | Path, array: np.ndarray) -> int:
    """float32 .npy, written finite (as write_exr); returns the number of values changed."""
    path = Path(path)
    data, changed = finite_values(np.asarray(array, dtype=np.float64), FLOAT_MAX)
    tmp = _atomic_target(path, ".npy")
    try:
        with open(tmp, "wb") as f:
            np.save(f, np.ascontiguousarray(data, dtype=np.float32))
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return changed


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
