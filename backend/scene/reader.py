"""Validated reading of JSON scene/material documents.

A :class:`Node` wraps one JSON object (or value) together with its *field path* and the file it
came from. Accessors check type and range and raise :class:`SceneError` naming file and path::

    materials.paint.roughness: expected a number in [0, 1], got -0.3

Every key of an object must be read by its parser; ``finish()`` reports the ones that were not
("unknown field"), so typos never pass silently.
"""
from __future__ import annotations

import json
import math
from contextvars import ContextVar
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..errors import SceneError
from ..limits import MAX_COORDINATE, MAX_INT_DIGITS, MAX_JSON_DEPTH, MAX_NUMBER, short
from .inputs import local_file

_MISSING = object()


# --------------------------------------------------------------------------- JSON documents

class HugeInt(float):
    """An integer literal with more than MAX_INT_DIGITS digits, kept as ±inf so that every
    numeric check refuses it, and described by its length in messages (never echoed)."""

    digits: int = 0

    def __new__(cls, text: str):
        self = super().__new__(cls, "-inf" if text.startswith("-") else "inf")
        self.digits = len(text.lstrip("-"))
        return self


def _parse_int(text: str):
    return int(text) if len(text) <= MAX_INT_DIGITS + 1 else HugeInt(text)


def read_json(text: str, where: str) -> Any:
    """Parse a JSON document with the limits of backend/limits.py: nesting depth and integer
    size. Errors are SceneErrors naming ``where`` (and the line, or the field path)."""
    try:
        data = json.loads(text, parse_int=_parse_int)
    except RecursionError:
        raise SceneError(where, "", f"arrays/objects nested deeper than {MAX_JSON_DEPTH} levels"
                                    f"{_deep_line(text)}") from None
    except json.JSONDecodeError as exc:
        raise SceneError(where, "", f"not valid JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}") from None
    except ValueError as exc:                      # e.g. a number the float parser refuses
        raise SceneError(where, "", f"not valid JSON: {short(exc, 200)}") from None
    if _depth_exceeds(data, MAX_JSON_DEPTH):
        raise SceneError(where, _deep_path(data, MAX_JSON_DEPTH),
                         f"arrays/objects nested deeper than {MAX_JSON_DEPTH} levels")
    return data


def _depth_exceeds(data: Any, limit: int) -> bool:
    """Is any array/object nested more than ``limit`` levels deep? (iterative: no recursion)"""
    stack = [(data, 1)] if isinstance(data, (list, dict)) else []
    while stack:
        value, depth = stack.pop()
        if depth > limit:
            return True
        children = value.values() if isinstance(value, dict) else value
        stack.extend((c, depth + 1) for c in children if isinstance(c, (list, dict)))
    return False


def _deep_path(data: Any, limit: int) -> str:
    """The field path of the first container nested deeper than ``limit``: its first segments,
    then "…" (the whole path is ``limit`` segments long)."""
    stack = [(data, [])]
    while stack:
        value, segments = stack.pop()
        if len(segments) >= limit:
            head = segments[:8]
            text = "".join(s if s.startswith("[") else ("." + s if i else s) for i, s in enumerate(head))
            return text + ("…" if len(segments) > len(head) else "")
        items = value.items() if isinstance(value, dict) else enumerate(value)
        for k, c in reversed(list(items)):
            if isinstance(c, (list, dict)):
                stack.append((c, segments + [f"[{k}]" if isinstance(k, int) else short(k)]))
    return ""


def _deep_line(text: str) -> str:
    """' (at line N)' where the nesting first passes MAX_JSON_DEPTH (brackets outside strings)."""
    import re
    depth = 0
    for m in re.finditer(r'"(?:[^"\\]|\\.)*"|[\[\]{}]', text):
        tok = m.group()
        if tok in "[{":
            depth += 1
            if depth > MAX_JSON_DEPTH:
                return f" (at line {text.count(chr(10), 0, m.start()) + 1})"
        elif tok in "]}":
            depth -= 1
    return ""


def _describe(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, HugeInt):
        return f"an integer of {value.digits} digits"
    if isinstance(value, (int, float)):
        if isinstance(value, int) and abs(value) >= 10 ** 15:
            return f"{float(value):g}"
        return repr(value)
    if isinstance(value, str):
        return repr(value) if len(value) < 60 else repr(value[:57] + "...")
    if isinstance(value, list):
        return f"a list of {len(value)}"
    if isinstance(value, dict):
        return "an object"
    return type(value).__name__


def _fmt(v) -> str:
    return str(int(v)) if float(v).is_integer() and abs(v) < 1e9 else f"{v:g}"


def _fmt_g(v) -> float | int:
    return int(v) if float(v).is_integer() and abs(v) < 1e15 else float(f"{v:.6g}")


def _range_text(lo, hi, lo_open, hi_open) -> str:
    if lo is not None and hi is not None:
        return f"in {'(' if lo_open else '['}{_fmt(lo)}, {_fmt(hi)}{')' if hi_open else ']'}"
    if lo is not None:
        return f"{'>' if lo_open else '>='} {_fmt(lo)}"
    if hi is not None:
        return f"{'<' if hi_open else '<='} {_fmt(hi)}"
    return ""


#: "error" while the CLI's ``--strict`` is on: overrides the scene's ``render.missing_textures``
#: (set around a load); None: the scene decides (backend/textures.py read_texture).
MISSING_TEXTURES: ContextVar = ContextVar("missing_textures", default=None)


class LoadContext:
    """Shared state while loading one document: its file, base folder, warnings, caches."""

    def __init__(self, where: str, base_dir: Path | None = None):
        self.where = where
        self.base_dir = base_dir if base_dir is not None else Path.cwd()
        self.warnings: list[str] = []
        self.cache: dict = {}
        self.missing_textures = MISSING_TEXTURES.get() or "magenta"   # render.missing_textures

    def warn(self, path: str, message: str) -> None:
        self.warnings.append(f"{self.where}: {path}: {message}" if path else f"{self.where}: {message}")

    def error(self, path: str, message: str) -> SceneError:
        return SceneError(self.where, path, message)

    def resolve(self, relative: str, field: str | None = None) -> Path:
        """``relative`` against the document's folder. With ``field``, a path that no file system
        accepts (too long, a NUL character) is a SceneError naming that field."""
        if field is not None:
            problem = path_problem(relative)
            if problem:
                raise self.error(field, problem)
        p = Path(relative)
        # local_file: a cluster worker reads its copy of the master's file (scene/inputs.py).
        return local_file(p if p.is_absolute() else (self.base_dir / p))

    def existing_file(self, relative: str, field: str, what: str = "file") -> Path:
        """The resolved path of a file that must exist; SceneError naming ``field`` otherwise."""
        path = self.resolve(relative, field)
        try:
            ok = path.is_file()
        except (OSError, ValueError) as exc:
            raise self.error(field, f"cannot use {what} {short(path, 200)}: "
                                    f"{getattr(exc, 'strerror', None) or exc}") from None
        if not ok:
            raise self.error(field, f"{what} not found: {short(path, 200)}")
        return path


def path_problem(text: str) -> str | None:
    """Why ``text`` cannot be a file path here (limits.MAX_PATH_LENGTH/COMPONENT), or None."""
    from ..limits import MAX_PATH_COMPONENT, MAX_PATH_LENGTH
    if not text:
        return "expected a file path, got an empty string"
    if "\x00" in text:
        return "a file path cannot contain a NUL character"
    if len(text) > MAX_PATH_LENGTH:
        return f"file path too long ({len(text)} characters, at most {MAX_PATH_LENGTH}): {short(text)}"
    for part in Path(text).parts:
        if len(part.encode("utf-8", "surrogateescape")) > MAX_PATH_COMPONENT:
            return (f"file path has a name longer than {MAX_PATH_COMPONENT} bytes "
                    f"({short(part)})")
    return None


class Node:
    """A JSON value at a field path. Object accessors consume keys; see ``finish``."""

    def __init__(self, value: Any, path: str, ctx: LoadContext):
        self.value = value
        self.path = path
        self.ctx = ctx
        self._used: set[str] = set()

    # ----------------------------------------------------------------- helpers
    def sub(self, key: str | int) -> str:
        if isinstance(key, int):
            return f"{self.path}[{key}]"
        key = short(key)
        return f"{self.path}.{key}" if self.path else key

    def fail(self, message: str, key: str | int | None = None) -> SceneError:
        return self.ctx.error(self.sub(key) if key is not None else self.path, message)

    def is_object(self) -> bool:
        return isinstance(self.value, dict)

    def require_object(self) -> "Node":
        if not isinstance(self.value, dict):
            raise self.fail(f"expected an object, got {_describe(self.value)}")
        return self

    def has(self, key: str) -> bool:
        return isinstance(self.value, dict) and key in self.value

    def _get(self, key: str, default: Any) -> Any:
        self.require_object()
        self._used.add(key)
        if key in self.value:
            return self.value[key]
        if default is _MISSING:
            raise self.fail("missing required field", key)
        return default

    def finish(self) -> None:
        """Raise on keys that no accessor read (unknown fields)."""
        if isinstance(self.value, dict):
            unknown = [k for k in self.value if k not in self._used and not k.startswith("_")]
            if unknown:
                raise self.fail(f"unknown field (allowed: {', '.join(sorted(self._used)) or 'none'})",
                                unknown[0])

    def ignore(self, *keys: str) -> None:
        """Mark keys as known (read elsewhere or deliberately ignored)."""
        self._used.update(keys)

    # ----------------------------------------------------------------- accessors
    def child(self, key: str, default: Any = _MISSING) -> "Node":
        return Node(self._get(key, default), self.sub(key), self.ctx)

    def optional_child(self, key: str) -> "Node | None":
        value = self._get(key, None)
        return None if value is None else Node(value, self.sub(key), self.ctx)

    def items(self) -> list["Node"]:
        """The elements of a JSON list as Nodes."""
        if not isinstance(self.value, list):
            raise self.fail(f"expected a list, got {_describe(self.value)}")
        return [Node(v, self.sub(i), self.ctx) for i, v in enumerate(self.value)]

    def entries(self) -> list[tuple[str, "Node"]]:
        """(key, Node) pairs of a JSON object (all keys consumed)."""
        self.require_object()
        self._used.update(self.value.keys())
        return [(k, Node(v, self.sub(k), self.ctx)) for k, v in self.value.items()]

    def string(self, key: str, default: Any = _MISSING, choices: tuple | list | None = None) -> str:
        value = self._get(key, default)
        if value is default and default is not _MISSING:
            return value
        if not isinstance(value, str):
            raise self.fail(f"expected a string, got {_describe(value)}", key)
        if choices is not None and value not in choices:
            raise self.fail(f"expected one of {', '.join(map(repr, choices))}, got {_describe(value)}", key)
        return value

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        value = self._get(key, default)
        if not isinstance(value, bool):
            raise self.fail(f"expected true or false, got {_describe(value)}", key)
        return value

    def number(self, key: str, default: Any = _MISSING, lo: float | None = None,
               hi: float | None = None, lo_open: bool = False, hi_open: bool = False) -> float:
        value = self._get(key, default)
        return check_number(value, self.sub(key), self.ctx, lo, hi, lo_open, hi_open)

    def integer(self, key: str, default: Any = _MISSING, lo: int | None = None,
                hi: int | None = None) -> int:
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer() and abs(value) < 2.0 ** 63:
                value = int(value)
            else:
                raise self.fail(f"expected an integer{' ' + _range_text(lo, hi, False, False) if lo is not None or hi is not None else ''}, got {_describe(value)}", key)
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise self.fail(f"expected an integer {_range_text(lo, hi, False, False)}, got {_describe(value)}", key)
        return value

    def vector(self, key: str, size: int, default: Any = _MISSING, lo: float | None = None,
               hi: float | None = None, nonzero: bool = False) -> np.ndarray:
        value = self._get(key, default)
        return check_vector(value, size, self.sub(key), self.ctx, lo, hi, nonzero)

    def rgb(self, key: str, default: Any = _MISSING, lo: float | None = 0.0,
            hi: float | None = None) -> np.ndarray:
        """An RGB triple; a single number means grey."""
        value = self._get(key, default)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value] * 3
        return check_vector(value, 3, self.sub(key), self.ctx, lo, hi, False, what="an RGB colour")

    def matrix4(self, key: str, default: Any = _MISSING) -> np.ndarray:
        """A 4×4 affine matrix given as 4 rows of 4 numbers (row-major, column vectors:
        p' = M p): entries within ±MAX_COORDINATE, last row [0, 0, 0, 1] (as Blender's
        matrix_world; a projective matrix has no meaning for an object), not singular."""
        return check_matrix4(self._get(key, default), self.sub(key), self.ctx)

    def motion(self, key: str = "motion") -> list[np.ndarray] | None:
        """Motion blur: ``to_world`` at 2 … MAX_MOTION_STEPS equally spaced times over the
        shutter, as a list of 4×4 matrices (each as ``matrix4``); None when absent."""
        if not self.has(key):
            return None
        value = self._get(key, None)
        path = self.sub(key)
        if not (isinstance(value, list) and 2 <= len(value) <= MAX_MOTION_STEPS):
            raise self.ctx.error(path, f"expected a list of 2 to {MAX_MOTION_STEPS} 4×4 matrices "
                                       f"(the transform over the shutter), got {_describe(value)}")
        return [check_matrix4(m, f"{path}[{i}]", self.ctx) for i, m in enumerate(value)]

    def param(self, key: str, default: Any = _MISSING, channels: int = 1, lo: float | None = None,
              hi: float | None = None, lo_open: bool = False, color: bool | None = None):
        """A texturable parameter: a constant (number/RGB) or ``{"texture": ...}``.

        Returns a :class:`backend.textures.Param`.
        """
        value = self._get(key, default)
        return parse_param(value, self.sub(key), self.ctx, channels, lo, hi, lo_open,
                           color if color is not None else channels == 3)

    def one_of(self, key: str, parsers: dict[str, Callable], default: Any = _MISSING):
        """Dispatch a child object on its "type" field."""
        child = self.child(key, default)
        return dispatch(child, parsers)


def dispatch(node: Node, parsers: dict[str, Callable]):
    node.require_object()
    kind = node.string("type")
    if kind not in parsers:
        raise node.fail(f"unknown type {short(kind)!r} (known: {', '.join(sorted(parsers))})", "type")
    result = parsers[kind](node)
    node.finish()
    return result


MAX_MOTION_STEPS = 64


def check_matrix4(value: Any, path: str, ctx: LoadContext) -> np.ndarray:
    """See ``Node.matrix4``."""
    if not (isinstance(value, list) and len(value) == 4 and
            all(isinstance(r, list) and len(r) == 4 for r in value)):
        raise ctx.error(path, f"expected a 4×4 matrix (4 rows of 4 numbers), got {_describe(value)}")
    rows = [check_vector(r, 4, f"{path}[{i}]", ctx, -MAX_COORDINATE, MAX_COORDINATE)
            for i, r in enumerate(value)]
    m = np.array(rows, dtype=np.float64)
    if np.max(np.abs(m[3] - [0.0, 0.0, 0.0, 1.0])) > 1e-6:
        raise ctx.error(f"{path}[3]", f"expected [0, 0, 0, 1] (an affine transform, as Blender's "
                                      f"matrix_world), got {[_fmt_g(v) for v in m[3]]}")
    m[3] = [0.0, 0.0, 0.0, 1.0]
    m[np.abs(m) < 1e-300] = 0.0             # subnormal entries only make LAPACK warn
    with np.errstate(all="ignore"):          # subnormal entries: det may warn
        det = float(np.linalg.det(m[:3, :3]))
    if not abs(det) >= 1e-12:
        raise ctx.error(path, "matrix is singular (zero scale?)")
    return m


def check_number(value: Any, path: str, ctx: LoadContext, lo=None, hi=None,
                 lo_open=False, hi_open=False) -> float:
    """A finite number in the given range. A bound left open is MAX_NUMBER in magnitude
    (backend/limits.py): beyond it, products formed while rendering could overflow."""
    rng = _range_text(lo, hi, lo_open, hi_open)
    what = f"a number {rng}".strip()
    if isinstance(value, bool) or not isinstance(value, (int, float)) or isinstance(value, HugeInt):
        raise ctx.error(path, f"expected {what}, got {_describe(value)}")
    value = float(value)
    if not math.isfinite(value):
        raise ctx.error(path, f"expected {what}, got {value}")
    if ((lo is not None and (value < lo or (lo_open and value == lo))) or
            (hi is not None and (value > hi or (hi_open and value == hi)))):
        raise ctx.error(path, f"expected {what}, got {_fmt(value)}")
    if abs(value) > MAX_NUMBER:
        capped = _range_text(-MAX_NUMBER if lo is None else lo, MAX_NUMBER if hi is None else hi,
                             lo_open, hi_open)
        raise ctx.error(path, f"expected a number {capped} (larger values overflow while "
                              f"rendering), got {_fmt(value)}")
    return value


def check_vector(value: Any, size: int, path: str, ctx: LoadContext, lo=None, hi=None,
                 nonzero=False, what: str | None = None) -> np.ndarray:
    what = what or f"a list of {size} numbers"
    if not isinstance(value, list) or len(value) != size:
        raise ctx.error(path, f"expected {what}, got {_describe(value)}")
    out = np.array([check_number(v, f"{path}[{i}]", ctx, lo, hi) for i, v in enumerate(value)])
    if nonzero and not np.any(out):
        raise ctx.error(path, "expected a non-zero vector")
    return out


def parse_param(value: Any, path: str, ctx, channels: int, lo, hi, lo_open: bool, color: bool):
    """A texturable parameter (``backend.textures.Param``): a number, an RGB colour, or
    ``{"texture": file, "colorspace": …, "channel": …, "scale": …}``."""
    from ..textures import ConstantParam, image_param
    if isinstance(value, dict):
        node = Node(value, path, ctx)
        file = node.string("texture")
        colorspace = node.string("colorspace", "auto", choices=("auto", "sRGB", "linear"))
        channel = node.integer("channel", -1, lo=-1, hi=3)
        # A parameter that cannot be negative cannot take a negative scale either.
        scale_lo = 0.0 if lo is not None and lo >= 0 else None
        if channels == 3:
            scale = node.rgb("scale", [1.0, 1.0, 1.0], lo=scale_lo)
        else:
            scale = np.asarray(node.number("scale", 1.0, lo=scale_lo))
        node.finish()
        return image_param(ctx, file, path, channels, channel, colorspace, color, lo, hi, scale)
    if channels == 3:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value] * 3
        v = check_vector(value, 3, path, ctx, lo, hi, what="an RGB colour or {\"texture\": ...}")
        return ConstantParam(v, 3)
    if isinstance(value, list):
        raise ctx.error(path, f"expected a number or {{\"texture\": ...}}, got a list of {len(value)}")
    return ConstantParam(check_number(value, path, ctx, lo, hi, lo_open), 1)
