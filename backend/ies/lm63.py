"""Reader for IES LM-63 photometric files (LM-63-1986, -1991, -1995, -2002, -2019).

Two steps, kept apart so each can be checked on its own:

* :func:`read_lm63` / :func:`parse_lm63` turn the bytes into an :class:`LM63File` holding exactly
  what the file says (header, keywords, tilt block, counts, angles, candela table as written).
  Anything malformed raises :class:`LM63Error` naming the file, the line and what was expected.
* :func:`to_cycles_frame` turns that into one table on a (horizontal, vertical) angle grid in the
  frame Cycles uses (docs/lights.md, IES lights), with the photometric type converted, horizontal symmetry
  expanded and the candela multiplier × ballast factor × ballast-lamp factor applied.

Conventions (they follow Cycles' ``util/ies.cpp`` of Blender 4.x/5.0 so a .blend renders alike):

* Type C (``photometric type 1``): vertical angle v = angle from the light's local −Z (nadir),
  horizontal angle h = the file's C-plane angle. Symmetries: one horizontal angle (axial) → same
  column at every h; last angle 90° (quadrilateral) → mirrored to 0–180°; last 180° (bilateral) →
  mirrored to 0–360°; a missing 360° column is added as a copy of 0° when the spacing shows it was
  meant. A file whose horizontal angles start at 90° (90–270° bilateral, 90–180° ...) is *shifted*
  by −90° before mirroring, exactly as Cycles does; note that a strict reading of LM-63 would keep
  the 90° plane at h = 90°, so such files come out rotated by −90° about the light axis (in Cycles
  too). Vertical angles stay as given (0–90°, 0–180°, 90–180° ...); intensity is zero outside them.
* Type B (``2``, floodlights): the file's vertical angles (plane tilt about the horizontal polar
  axis) become h, its horizontal angles (in-plane angle H) become v, both shifted by +90° (a
  0–90° half is mirrored first). So H = −90° → local −Z, H = +90° → local +Z, and the beam axis
  (H = V = 0) points along local −X; h > 180° (the local +X half space, behind a floodlight) is
  zero. The solid-angle element sin v dv dh equals the type-B cos H dH dV. Rotate the light to aim
  the beam (Cycles: "users can just rotate the light").
* Type A (``3``): v = V + 90°, h = 180° − H (a 0–90° half is mirrored to 180–270°): the type-A
  reference axis (H = V = 0) points along local +Y, +H turns towards local −X, and h outside
  90–270° is zero. Supported as Cycles does; no real type-A file was available to test with.

TILT: ``TILT=INCLUDE`` blocks are parsed, validated and kept in :attr:`LM63File.tilt` but **not
applied** (as in Cycles): the factors describe how lamp output changes when the luminaire is
mounted tilted from its photometric position; the renderer assumes it is mounted as measured
(factor 1). ``TILT=<file name>`` (an external tilt file) is likewise ignored, with a warning.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import LaminaError

# ------------------------------------------------------------------------------------------------
# Errors

class LM63Error(LaminaError):
    """A malformed LM-63 file: ``name: line N: message``. ``line`` is 1-based (None = whole file)."""

    def __init__(self, name: str, line: int | None, message: str):
        self.name, self.line, self.message = name, line, message
        where = f"line {line}: " if line is not None else ""
        super().__init__(f"{name}: {where}{message}")

    def detail(self) -> str:
        """The message without the file name (for embedding in a scene-file error)."""
        return (f"line {self.line}: " if self.line is not None else "") + self.message


# ------------------------------------------------------------------------------------------------
# Data

PHOTOMETRIC_TYPES = {1: "C", 2: "B", 3: "A"}
UNITS = {1: "feet", 2: "meters"}
VERSIONS = {  # first line → standard
    "IESNA:LM-63-1995": "LM-63-1995",
    "IESNA:LM-63-2002": "LM-63-2002",
    "IES:LM-63-2019": "LM-63-2019",
    "IESNA:LM-63-2019": "LM-63-2019",
    "IESNA91": "LM-63-1991",
}


@dataclass
class TiltBlock:
    """A TILT=INCLUDE block: lamp-to-luminaire geometry (1..3), tilt angles [deg] and factors."""
    geometry: int
    angles: np.ndarray
    factors: np.ndarray


@dataclass
class LM63File:
    """The content of an LM-63 file as written (no symmetry expansion, factors not applied)."""
    name: str
    version: str                       # "LM-63-1986" (no version line), "LM-63-1991", ... "-2019"
    version_line: str | None           # the first line when it names the standard
    keywords: list[tuple[str, str]]    # ([KEY], value) in file order; [MORE] lines joined by "\n"
    header_lines: list[str]            # free-text lines (LM-63-1986) and any non-keyword lines
    tilt: str                          # "NONE", "INCLUDE" or the external file name
    tilt_block: TiltBlock | None
    lamps: int
    lumens_per_lamp: float             # −1: absolute photometry (no rated lamp lumens)
    multiplier: float
    photometric_type: int              # 1 = C, 2 = B, 3 = A
    units: int                         # 1 = feet, 2 = metres
    width: float
    length: float
    height: float
    ballast_factor: float
    ballast_lamp_factor: float         # "future use" in LM-63-2019 (1.0 there); applied as Cycles does
    input_watts: float
    vertical_angles: np.ndarray        # (nv,) degrees, strictly increasing
    horizontal_angles: np.ndarray      # (nh,) degrees, strictly increasing
    candela: np.ndarray                # (nh, nv) as written (one row per horizontal angle)
    warnings: list[str] = field(default_factory=list)

    @property
    def type_letter(self) -> str:
        return PHOTOMETRIC_TYPES[self.photometric_type]

    @property
    def factor(self) -> float:
        """Candela multiplier × ballast factor × ballast-lamp factor (what Cycles applies)."""
        return self.multiplier * self.ballast_factor * self.ballast_lamp_factor

    @property
    def stated_lumens(self) -> float | None:
        """Rated lamp lumens (lamps × lumens per lamp); None for absolute photometry (−1)."""
        if self.lumens_per_lamp <= 0:
            return None
        return self.lamps * self.lumens_per_lamp

    def keyword(self, key: str, default: str | None = None) -> str | None:
        """The value of the first ``[KEY]`` (case-insensitive), [MORE] lines joined by newlines."""
        key = key.strip().upper()
        for k, v in self.keywords:
            if k == key:
                return v
        return default

    def keyword_dict(self) -> dict[str, list[str]]:
        out: dict[str, list[str]] = {}
        for k, v in self.keywords:
            out.setdefault(k, []).append(v)
        return out

    @property
    def symmetry(self) -> str:
        """'axial', 'quadrilateral', 'bilateral' or 'none' (from the horizontal angles)."""
        return describe_symmetry(self)[0]


# ------------------------------------------------------------------------------------------------
# Text → tokens

_NUMBER = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?$")
_KEYWORD = re.compile(r"^\s*\[([^\]]*)\]\s?(.*)$")
_TILT = re.compile(r"^\s*TILT\s*=\s*(.*?)\s*$", re.IGNORECASE)


def decode_text(data: bytes) -> str:
    """UTF-8 if the bytes are valid UTF-8, else Latin-1 (never fails: keyword text is free-form)."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


class _Tokens:
    """The whitespace/comma-separated tokens after the TILT line, each with its line number."""

    def __init__(self, name: str, lines: list[str], first_line: int):
        self.name = name
        self.items: list[tuple[str, int]] = []
        for i, line in enumerate(lines):
            for tok in line.replace(",", " ").split():
                self.items.append((tok, first_line + i))
        self.pos = 0
        self.last_line = first_line + max(len(lines) - 1, 0)

    def error(self, line: int | None, message: str) -> LM63Error:
        return LM63Error(self.name, line, message)

    def number(self, what: str) -> float:
        if self.pos >= len(self.items):
            raise self.error(self.last_line, f"unexpected end of file: expected {what}")
        tok, line = self.items[self.pos]
        if not _NUMBER.match(tok):
            raise self.error(line, f"expected {what}: a number, got {_quote(tok)}")
        value = float(tok)
        if not math.isfinite(value) or abs(value) > MAX_VALUE:
            raise self.error(line, f"expected {what}: a finite number of magnitude at most "
                                   f"{MAX_VALUE:g}, got {_quote(tok)}")
        self.pos += 1
        return value

    def integer(self, what: str, lo: int | None = None, hi: int | None = None) -> int:
        line = self.line()
        value = self.number(what)
        if not value.is_integer() or (lo is not None and value < lo) or (hi is not None and value > hi):
            rng = f" in {lo}..{hi}" if lo is not None and hi is not None else (f" >= {lo}" if lo is not None else "")
            raise self.error(line, f"expected {what} (an integer{rng}), got {_quote(self.items[self.pos - 1][0])}")
        return int(value)

    def positive(self, what: str) -> float:
        line = self.line()
        value = self.number(what)
        if not value > 0:
            raise self.error(line, f"expected {what} > 0, got {_quote(self.items[self.pos - 1][0])}")
        return value

    def array(self, count: int, what: str, item: str, detail: str = "") -> tuple[np.ndarray, list[int]]:
        """``count`` numbers (``what`` plural, ``item`` singular); on a premature end, say how many
        were found."""
        start = self.pos
        if count > len(self.items) - self.pos:
            # Said before reading (and allocating): the counts may be corrupt and huge.
            raise self.error(self.last_line,
                             f"unexpected end of file: expected {count} {what}{detail}, found only "
                             f"{sum(1 for t, _ in self.items[self.pos:self.pos + count] if _NUMBER.match(t))} "
                             f"(truncated file, or wrong angle counts?)")
        out = np.empty(count)
        lines = []
        for i in range(count):
            if self.pos >= len(self.items):
                raise self.error(self.last_line,
                                 f"unexpected end of file: expected {count} {what}{detail}, found only "
                                 f"{i} (truncated file, or wrong angle counts?)")
            lines.append(self.line())
            out[i] = self.number(f"{item} {i + 1} of {count}{detail}")
        assert self.pos == start + count
        return out, lines

    def line(self) -> int:
        return self.items[self.pos][1] if self.pos < len(self.items) else self.last_line

    def rest(self) -> list[tuple[str, int]]:
        return self.items[self.pos:]


# ------------------------------------------------------------------------------------------------
# Parsing

MAX_ANGLES = 100_000  # guards against absurd counts from a corrupt header
MAX_VALUE = 1e30     # any number in the file (as every number in a scene, backend/limits.py)
MAX_CANDELA = 1e15   # the largest intensity once the factors are applied: searchlights reach 1e9 cd


def _quote(tok: str) -> str:
    return repr(tok) if len(tok) <= 40 else repr(tok[:37] + "...")


def read_lm63(path: str | Path) -> LM63File:
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise LaminaError(f"{path}: IES file not found") from None
    except OSError as exc:
        raise LaminaError(f"{path}: cannot read IES file ({exc.strerror or exc})") from None
    return parse_lm63(data, name=str(path))


def parse_lm63(data: bytes | str, name: str = "<IES data>") -> LM63File:
    """Parse LM-63 text (bytes are decoded as UTF-8, falling back to Latin-1)."""
    text = decode_text(data) if isinstance(data, (bytes, bytearray)) else str(data)
    # A DOS end-of-file byte (Ctrl-Z) and NULs are noise, not content.
    text = text.replace("\x1a", " ").replace("\x00", " ")
    lines = text.splitlines()
    if not any(line.strip() for line in lines):
        raise LM63Error(name, None, "empty file (expected an IES LM-63 photometric file)")

    # ---- header: optional version line, keyword / free-text lines, then TILT=
    first = lines[0].strip()
    version_line = None
    version = "LM-63-1986"
    start = 0
    key = first.upper().replace(" ", "")
    if key in VERSIONS:
        version_line, version, start = first, VERSIONS[key], 1
    elif key.startswith("IESNA") or key.startswith("IES:"):
        version_line, version, start = first, first, 1  # unknown revision: keep its own name

    tilt_index = None
    for i in range(start, len(lines)):
        if _TILT.match(lines[i]) and not lines[i].lstrip().startswith("["):
            tilt_index = i
            break
    if tilt_index is None:
        raise _missing_tilt(name, lines, start)

    keywords: list[tuple[str, str]] = []
    header_lines: list[str] = []
    for i in range(start, tilt_index):
        raw = lines[i].rstrip()
        m = _KEYWORD.match(raw)
        if m:
            k, v = m.group(1).strip().upper(), m.group(2).strip()
            if k == "MORE" and keywords:
                pk, pv = keywords[-1]
                keywords[-1] = (pk, f"{pv}\n{v}" if pv else v)
            else:
                keywords.append((k, v))
        elif raw.strip():
            header_lines.append(raw.strip())

    warnings: list[str] = []
    tilt_value = _TILT.match(lines[tilt_index]).group(1)
    tilt_upper = tilt_value.upper()
    tokens = _Tokens(name, lines[tilt_index + 1:], tilt_index + 2)
    tilt_block = None
    if tilt_upper == "NONE":
        tilt = "NONE"
    elif tilt_upper == "INCLUDE":
        tilt = "INCLUDE"
        tilt_block = _read_tilt(tokens)
    elif tilt_value:
        tilt = tilt_value
        warnings.append(f"TILT={tilt_value}: external tilt file ignored (as Cycles does)")
    else:
        raise LM63Error(name, tilt_index + 1, "expected 'TILT=NONE', 'TILT=INCLUDE' or 'TILT=<file>', got 'TILT=' with no value")

    # ---- photometric header lines
    lamps = tokens.integer("the number of lamps", lo=0)
    lumens = tokens.number("lumens per lamp (-1 for absolute photometry)")
    line = m_line = tokens.line()
    multiplier = tokens.number("the candela multiplier")
    if not multiplier > 0:
        raise tokens.error(line, f"expected the candela multiplier > 0, got {multiplier:g}")
    nv = tokens.integer("the number of vertical angles", lo=1, hi=MAX_ANGLES)
    nh = tokens.integer("the number of horizontal angles", lo=1, hi=MAX_ANGLES)
    line = tokens.line()
    ptype = tokens.integer("the photometric type (1 = C, 2 = B, 3 = A)", lo=1, hi=3)
    units = tokens.integer("the units type (1 = feet, 2 = meters)", lo=1, hi=2)
    width = tokens.number("the luminous opening width")
    length = tokens.number("the luminous opening length")
    height = tokens.number("the luminous opening height")
    ballast = tokens.positive("the ballast factor")
    ballast_lamp = tokens.positive("the ballast-lamp photometric factor (future use, 1)")
    watts = tokens.number("the input watts")

    if nv < 2:
        raise tokens.error(line, f"expected at least 2 vertical angles, the file declares {nv}")

    # ---- angles and candela table
    v_line = tokens.line()
    v, v_lines = tokens.array(nv, "vertical angles", "vertical angle")
    h_line = tokens.line()
    h, h_lines = tokens.array(nh, "horizontal angles", "horizontal angle")
    _check_increasing(name, v, v_lines, "vertical")
    _check_increasing(name, h, h_lines, "horizontal")
    _check_ranges(name, ptype, v, v_line, h, h_line)

    table, t_lines = tokens.array(nv * nh, "candela values", "candela value",
                                   f" ({nh} horizontal × {nv} vertical angles)")
    if np.any(table < 0):
        k = int(np.argmax(table < 0))
        raise LM63Error(name, t_lines[k], f"expected candela values >= 0, got {table[k]:g}")
    candela = table.reshape(nh, nv)
    peak = float(table.max()) * multiplier * ballast * ballast_lamp
    if peak > MAX_CANDELA:
        raise LM63Error(name, m_line, f"the candela multiplier ({multiplier:g}) × ballast factor "
                                      f"({ballast:g}) × ballast-lamp factor ({ballast_lamp:g}) × the "
                                      f"largest candela value ({table.max():g}) = {peak:g} cd, above "
                                      f"{MAX_CANDELA:g} cd (no luminaire is that bright: a corrupt file?)")

    # ---- trailing content: words (END, a Ctrl-Z, notes) are tolerated; extra numbers mean the
    # declared counts do not match the data.
    for tok, ln in tokens.rest():
        if _NUMBER.match(tok):
            raise LM63Error(name, ln, f"unexpected number {_quote(tok)} after the candela table: the file "
                                      f"declares {nv} vertical × {nh} horizontal angles = {nv * nh} "
                                      f"candela values, but more numbers follow (wrong angle counts?)")

    return LM63File(
        name=name, version=version, version_line=version_line, keywords=keywords,
        header_lines=header_lines, tilt=tilt, tilt_block=tilt_block, lamps=lamps,
        lumens_per_lamp=lumens, multiplier=multiplier, photometric_type=ptype, units=units,
        width=width, length=length, height=height, ballast_factor=ballast,
        ballast_lamp_factor=ballast_lamp, input_watts=watts, vertical_angles=v,
        horizontal_angles=h, candela=candela, warnings=warnings)


def _missing_tilt(name: str, lines: list[str], start: int) -> LM63Error:
    # Point at the first line that looks like photometric data (numbers only): that is where the
    # TILT line should have been.
    for i in range(start, len(lines)):
        toks = lines[i].replace(",", " ").split()
        if len(toks) >= 3 and all(_NUMBER.match(t) for t in toks):
            return LM63Error(name, i + 1, "expected a 'TILT=NONE' or 'TILT=INCLUDE' line before the "
                                          f"photometric data, got {lines[i].strip()[:40]!r}")
    return LM63Error(name, len(lines), "end of file reached without a 'TILT=' line (expected "
                                       "'TILT=NONE' or 'TILT=INCLUDE' after the header): not an IES LM-63 file?")


def _read_tilt(tokens: _Tokens) -> TiltBlock:
    geometry = tokens.integer("the TILT=INCLUDE lamp-to-luminaire geometry (1, 2 or 3)", lo=1, hi=3)
    count = tokens.integer("the number of tilt angles", lo=1, hi=MAX_ANGLES)
    angles, lines = tokens.array(count, "tilt angles", "tilt angle")
    _check_increasing(tokens.name, angles, lines, "tilt")
    factors, flines = tokens.array(count, "tilt multiplying factors", "tilt factor")
    if np.any(factors < 0):
        k = int(np.argmax(factors < 0))
        raise tokens.error(flines[k], f"expected tilt factors >= 0, got {factors[k]:g}")
    return TiltBlock(geometry, angles, factors)


def _check_increasing(name: str, a: np.ndarray, lines: list[int], what: str) -> None:
    bad = np.nonzero(np.diff(a) <= 0)[0]
    if bad.size:
        k = int(bad[0]) + 1
        raise LM63Error(name, lines[k], f"{what} angles must increase strictly: angle {k + 1} is "
                                        f"{a[k]:g}° after {a[k - 1]:g}° (wrong angle counts?)")


def _check_ranges(name, ptype, v, v_line, h, h_line) -> None:
    if ptype == 1:
        v_lo, v_hi, h_lo, h_hi = 0.0, 180.0, 0.0, 360.0
    else:
        v_lo, v_hi, h_lo, h_hi = -90.0, 90.0, -90.0, 90.0
    t = PHOTOMETRIC_TYPES[ptype]
    tol = 1e-4
    if v[0] < v_lo - tol or v[-1] > v_hi + tol:
        raise LM63Error(name, v_line, f"type {t} vertical angles must lie in {v_lo:g}..{v_hi:g}°, "
                                      f"got {v[0]:g}..{v[-1]:g}°")
    if h[0] < h_lo - tol or h[-1] > h_hi + tol:
        raise LM63Error(name, h_line, f"type {t} horizontal angles must lie in {h_lo:g}..{h_hi:g}°, "
                                      f"got {h[0]:g}..{h[-1]:g}°")


# ------------------------------------------------------------------------------------------------
# Conversion to the Cycles frame

ANGLE_TOL = 1e-4  # degrees; Cycles' angle_close() tolerance


def _close(a: float, b: float) -> bool:
    return abs(a - b) < ANGLE_TOL


def describe_symmetry(f: LM63File) -> tuple[str, str]:
    """(symmetry, range text). Symmetry ∈ axial, quadrilateral, bilateral, none."""
    h = f.horizontal_angles
    rng = f"{h[0]:g}..{h[-1]:g}"
    if f.photometric_type == 1:
        if h.size == 1:
            return "axial", rng
        span = h[-1] - h[0]
        if _close(span, 90.0):
            return "quadrilateral", rng
        if _close(span, 180.0):
            return "bilateral", rng
        return "none", rng
    # Types A/B: horizontal angles from 0 mean the file gives one half, mirrored about H = 0.
    return ("bilateral" if _close(h[0], 0.0) else "none"), rng


def to_cycles_frame(f: LM63File) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(h_deg (nh,), v_deg (nv,), candela (nh, nv)) in the Cycles frame, factors applied.

    h: 0° = local −Y, 90° = −X, 180° = +Y, 270° = +X; v: 0° = local −Z. Type C tables cover h =
    0..360° (last column = first); type B covers at most h = 0..180°, type A 90..270°.
    """
    table = f.candela * f.factor
    h = f.horizontal_angles.astype(np.float64).copy()
    v = f.vertical_angles.astype(np.float64).copy()
    if f.photometric_type == 1:
        h, table = _expand_type_c(f, h, table)
    elif f.photometric_type == 2:
        h, v, table = _convert_type_b(h, v, table)
    else:
        h, v, table = _convert_type_a(h, v, table)
    return h, v, np.ascontiguousarray(table, dtype=np.float64)


def _mirror(angles: np.ndarray, rows: np.ndarray, about: float) -> tuple[np.ndarray, np.ndarray]:
    """Append the reflection about ``about`` (= the last angle) of all but the last entry."""
    n = angles.size
    idx = np.arange(n - 2, -1, -1)
    return (np.concatenate([angles, 2.0 * about - angles[idx]]),
            np.concatenate([rows, rows[idx]], axis=0))


def _expand_type_c(f: LM63File, h: np.ndarray, table: np.ndarray):
    name = f.name
    if h.size == 1:
        # One horizontal angle (whatever its value): rotationally symmetric.
        return np.array([0.0, 360.0]), np.concatenate([table, table], axis=0)
    if _close(h[0], 90.0):
        h = h - 90.0  # Cycles: a 90..270 (or 90..180) file is relabelled to start at 0
    if not _close(h[0], 0.0):
        raise LM63Error(name, None, f"type C horizontal angles must start at 0° (or 90°), got "
                                    f"{f.horizontal_angles[0]:g}°")
    h[0] = 0.0
    if _close(h[-1], 90.0):
        h[-1] = 90.0
        h, table = _mirror(h, table, 90.0)
    if _close(h[-1], 180.0):
        h[-1] = 180.0
        h, table = _mirror(h, table, 180.0)
    if not _close(h[-1], 360.0):
        # Some files omit the 360° column (equal to 0°); add it when the spacing shows it (Cycles).
        gap = 360.0 - h[-1]
        if h.size >= 2 and (_close(h[-1] - h[-2], gap) or _close(h[1] - h[0], gap)):
            h = np.append(h, 360.0)
            table = np.concatenate([table, table[:1]], axis=0)
        else:
            hf = f.horizontal_angles
            raise LM63Error(name, None, f"type C horizontal angles {hf[0]:g}..{hf[-1]:g}° match no LM-63 "
                                        "symmetry (expected one angle, 0..90, 0..180, 0..360 or 90..270)")
    h[-1] = 360.0
    return h, table


def _half_to_full(a: np.ndarray):
    """0..90 → −90..90 mirrored about 0, as index map and angles (then shifted by +90)."""
    n = a.size
    idx = np.concatenate([np.arange(n - 1, 0, -1), np.arange(n)])
    sign = np.concatenate([-np.ones(n - 1), np.ones(n)])
    return sign * a[idx] + 90.0, idx


def _convert_type_b(h: np.ndarray, v: np.ndarray, table: np.ndarray):
    # Transpose: the file's vertical angles (plane tilts) become h, its horizontal angles v.
    table = table.T  # now (file V, file H) = (h, v)
    h_new, v_new = v, h
    if _close(h_new[0], 0.0):
        h_new, idx = _half_to_full(h_new)
        table = table[idx, :]
    else:
        h_new = h_new + 90.0
    if _close(v_new[0], 0.0):
        v_new, idx = _half_to_full(v_new)
        table = table[:, idx]
    else:
        v_new = v_new + 90.0
    return h_new, v_new, table


def _convert_type_a(h: np.ndarray, v: np.ndarray, table: np.ndarray):
    v_new = v + 90.0
    n = h.size
    rev = np.arange(n - 1, -1, -1)
    h_new = 180.0 - h[rev]
    rows = table[rev]
    if _close(h[0], 0.0):
        h_new = np.concatenate([h_new, 180.0 + h[1:]])
        rows = np.concatenate([rows, table[1:]], axis=0)
    return h_new, v_new, rows
