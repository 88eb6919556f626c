"""Frame files: how a session hands images to its client (docs/session.md).

A frame file is a 64-byte little-endian header followed by float32 RGBA pixels, row 0 at the
**top**, linear scene-referred (alpha = coverage with a transparent film, else 1; 0 outside a
crop region)::

    offset  type      field
    0       8 bytes   magic  b"LAMFRAME"
    8       uint32    format version (1)
    12      uint32    header size in bytes (64)
    16      uint64    frame number (increases by one per frame of the session)
    24      uint64    edit generation the image was rendered from
    32      uint32    width     36  uint32 height     40  uint32 channels (4)
    44      uint32    samples per pixel (at full resolution; 1 for a reduced-resolution pass)
    48      uint32    scale: 1 = full resolution, k = a pass at 1/k of the width and height
    52      uint32    flags: bit 0 = final (the sample target is reached)
    56      8 bytes   reserved (zero)

The writer fills a temporary file and renames it over the slot (``frame-0.bin``, ``frame-1.bin``,
alternating), so a reader never sees a half-written frame; the header says which frame it got
(a slot may already hold a newer frame than the event that named it). A final frame comes with a
*feature file* (``features-0.bin`` / ``-1.bin``): the same header (the frame's number) over 6
channels, albedo RGB and normal XYZ, for a denoiser.
"""
from __future__ import annotations

import os
import struct
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

MAGIC = b"LAMFRAME"
VERSION = 1
HEADER = struct.Struct("<8sIIQQIIIIII8x")
assert HEADER.size == 64
FLAG_FINAL = 1
SLOTS = 2


@dataclass
class FrameInfo:
    frame: int
    generation: int
    width: int
    height: int
    channels: int
    spp: int
    scale: int
    final: bool


class FrameWriter:
    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.count = 0

    def write(self, rgba: np.ndarray, generation: int, spp: int, scale: int, final: bool) -> tuple[Path, int]:
        """Write a (height, width, 4) image; returns (path, frame number)."""
        self.count += 1
        frame = self.count
        return self._write("frame", frame, rgba, generation, spp, scale, final), frame

    def write_features(self, features: np.ndarray, frame: int, generation: int, spp: int) -> Path:
        """Write the denoising features of frame number ``frame`` (a final one): (height, width, 6)
        albedo RGB and normal XYZ, in a *feature file* (``features-0.bin`` / ``-1.bin``: the frame
        file's layout with 6 channels and the frame's number, so the client can tell that they
        belong together)."""
        return self._write("features", frame, features, generation, spp, 1, True)

    def _write(self, kind: str, frame: int, pixels: np.ndarray, generation: int, spp: int, scale: int,
               final: bool) -> Path:
        h, w, c = pixels.shape
        header = HEADER.pack(MAGIC, VERSION, HEADER.size, frame, generation, w, h, c, spp, scale,
                             FLAG_FINAL if final else 0)
        path = self.folder / f"{kind}-{frame % SLOTS}.bin"
        tmp = self.folder / f".{kind}-{frame % SLOTS}.tmp"
        with open(tmp, "wb") as f:
            f.write(header)
            f.write(np.ascontiguousarray(pixels, dtype="<f4").tobytes())
        for attempt in range(50):
            try:
                os.replace(tmp, path)
                break
            except PermissionError:          # Windows: the reader has the old file open
                time.sleep(0.005)
        else:
            os.replace(tmp, path)
        return path


def read_header(data: bytes) -> FrameInfo:
    if len(data) < HEADER.size:
        raise ValueError("frame file too short")
    magic, version, size, frame, generation, w, h, c, spp, scale, flags = HEADER.unpack_from(data)
    if magic != MAGIC or version != VERSION or size != HEADER.size:
        raise ValueError("not a Lamina frame file (version 1)")
    return FrameInfo(frame, generation, w, h, c, spp, scale, bool(flags & FLAG_FINAL))


def read_frame(path) -> tuple[FrameInfo, np.ndarray]:
    """(header, pixels (height, width, channels) float32, row 0 at the top)."""
    data = Path(path).read_bytes()
    info = read_header(data)
    n = info.width * info.height * info.channels
    pixels = np.frombuffer(data, dtype="<f4", count=n, offset=HEADER.size)
    return info, pixels.reshape(info.height, info.width, info.channels)
