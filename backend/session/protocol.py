"""Session commands (stdin) and events (stdout): one JSON object per line (docs/session.md).

Commands::

    {"cmd": "scene", "generation": 1, "path": "/tmp/s/scene.json"}
    {"cmd": "scene", "generation": 1, "scene": {...}, "base": "/tmp/s"}
    {"cmd": "update", "generation": 2, "changes": {"camera": {...}, "materials": {"A": {...}}}}
    {"cmd": "update", "generation": 3, "changes_file": "/tmp/s/update-3.json"}
    {"cmd": "samples", "samples": 64}
    {"cmd": "ping", "id": 7}
    {"cmd": "stop"}

Generations are integers chosen by the client and must not decrease. ``update`` changes name
scene-file sections: ``film``, ``camera``, ``render``, ``objects``, ``lights`` and ``world``
replace the section; ``materials`` and ``meshes`` merge by name (``null`` removes an entry).
"""
from __future__ import annotations

import json
import queue
import sys
import threading
from pathlib import Path

import numpy as np

from ..errors import LaminaError
from ..limits import MAX_SPP

PROTOCOL = 1
#: The scene file's sections the session reads. ``passes`` and ``views`` are checked as `render`
#: checks them and otherwise unused: the viewport shows the combined image of the scene's camera.
SECTIONS = ("film", "camera", "render", "materials", "meshes", "objects", "lights", "world", "passes", "views")
MERGED_SECTIONS = ("materials", "meshes")
COMMANDS = ("scene", "update", "samples", "ping", "stop")
#: Commands after which the current image is out of date (the render loop abandons its work).
RESTARTING = ("scene", "update", "stop")


class ProtocolError(LaminaError):
    """A command the session cannot understand (reported, then ignored)."""


#: Largest generation: frames carry it as a 64-bit field (frames.py) and clients read it as a
#: signed 64-bit integer.
MAX_GENERATION = 2 ** 63 - 1


def _generation(msg: dict) -> int:
    g = msg.get("generation")
    if isinstance(g, bool) or not isinstance(g, int) or not 0 <= g <= MAX_GENERATION:
        raise ProtocolError(f"{msg['cmd']}: 'generation' must be an integer from 0 to 2^63 - 1, "
                            f"got {_describe(g)}")
    return g


def _describe(value) -> str:
    from ..scene.reader import _describe as describe
    return describe(value)


def _string(msg: dict, key: str) -> str:
    value = msg.get(key)
    if not isinstance(value, str):
        raise ProtocolError(f"{msg['cmd']}: '{key}' must be a string, got {_describe(value)}")
    from ..scene.reader import path_problem
    problem = path_problem(value)
    if problem:
        raise ProtocolError(f"{msg['cmd']}: '{key}': {problem}")
    return value


def _read_json(text: str, what: str):
    """JSON with the scene reader's limits (nesting depth, integer digits): a command nested
    100 000 deep or a 5 000-digit number is an error, not a dead reader."""
    from ..errors import SceneError
    from ..scene.reader import read_json
    try:
        return read_json(text, what)
    except SceneError as exc:
        raise ProtocolError(str(exc)) from None


def _read_json_file(path: str, what: str):
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ProtocolError(f"{what}: cannot read {path}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise ProtocolError(f"{what}: {path} is not valid UTF-8 text: {exc}") from None
    return _read_json(text, f"{what}: {path}")


def parse_command(line: str) -> dict:
    """A validated command: ``{"cmd": ...}`` with its fields (files named by the command are
    read here, so the render loop gets the data)."""
    msg = _read_json(line, "not a JSON command")
    if not isinstance(msg, dict):
        raise ProtocolError(f"a command must be a JSON object, got {_describe(msg)}")
    cmd = msg.get("cmd")
    if cmd not in COMMANDS:
        raise ProtocolError(f"unknown command {_describe(cmd)} (known: {', '.join(COMMANDS)})")
    if cmd == "scene":
        _generation(msg)
        if "base" in msg:
            _string(msg, "base")
        if "path" in msg:
            path = Path(_string(msg, "path"))
            msg["scene"] = _read_json_file(str(path), "scene")
            msg.setdefault("base", str(path.parent))
            msg["where"] = str(path)
        elif not isinstance(msg.get("scene"), dict):
            raise ProtocolError("scene: give 'path' (a scene file) or 'scene' (the document)")
        else:
            msg["where"] = "<session scene>"
    elif cmd == "update":
        _generation(msg)
        if "changes_file" in msg:
            msg["changes"] = _read_json_file(_string(msg, "changes_file"), "update")
        changes = msg.get("changes")
        if not isinstance(changes, dict):
            raise ProtocolError("update: 'changes' must be an object of scene sections")
        unknown = [k for k in changes if k not in SECTIONS]
        if unknown:
            raise ProtocolError(f"update: unknown section(s) {', '.join(map(repr, unknown))} "
                                f"(known: {', '.join(SECTIONS)})")
        for key in MERGED_SECTIONS:
            if key in changes and not isinstance(changes[key], dict):
                raise ProtocolError(f"update: '{key}' must be an object of entries by name (null removes one)")
    elif cmd == "samples":
        n = msg.get("samples")
        if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= MAX_SPP:
            raise ProtocolError(f"samples: 'samples' must be an integer from 0 (no limit) to {MAX_SPP}, "
                                f"got {_describe(n)}")
    elif cmd == "ping":
        try:
            json.dumps(msg.get("id"), allow_nan=False)
        except (TypeError, ValueError):
            raise ProtocolError(f"ping: 'id' must be a JSON value the answer can carry (finite numbers "
                                f"only), got {_describe(msg.get('id'))}") from None
    return msg


def read_command(line: str):
    """``parse_command``, or the ProtocolError that answers the line, whatever it holds (the
    reader thread must live on: a dead reader left the session deaf and never exiting)."""
    try:
        return parse_command(line)
    except ProtocolError as exc:
        return exc
    except Exception as exc:  # noqa: BLE001 - any line gets an answer
        return ProtocolError(f"cannot read this command ({type(exc).__name__}: {str(exc)[:200]}): "
                             f"{line[:80]!r}")


class EventWriter:
    """Writes events as JSON lines and flushes each (only the render loop's thread writes)."""

    def __init__(self, stream=None):
        self.stream = stream if stream is not None else sys.stdout

    def __call__(self, event: str, **fields) -> None:
        self.stream.write(json.dumps({"event": event, **fields}, allow_nan=False) + "\n")
        self.stream.flush()


_EOF = object()


class CommandQueue:
    """Commands read from a stream by a daemon thread, so the render loop can look for them
    between (and during) work items without blocking, and block on them when idle (no CPU).

    Each entry is a parsed command, a ProtocolError, or end-of-input (the client went away:
    the session ends, so it never outlives its client)."""

    def __init__(self, stream=None):
        self._queue: queue.Queue = queue.Queue()
        self._restart = threading.Event()
        #: The same flag as a uint8[1] for the compiled bounce loop, which reads it before every
        #: bounce (backend/kernels/item_loop.py; ``PathTracer.stop_flag``).
        self.restart_flag = np.zeros(1, np.uint8)
        self._stream = stream if stream is not None else sys.stdin
        self._thread = threading.Thread(target=self._read, name="lamina-session-stdin", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        try:
            for line in self._stream:
                line = line.strip()
                if not line:
                    continue
                item = read_command(line)
                # Queued before the flag is raised: a raised flag always has its command waiting
                # (a flag raised for a command already taken only costs one empty look).
                self._queue.put(item)
                if isinstance(item, dict) and item["cmd"] in RESTARTING:
                    self._raise_restart()
        except (OSError, ValueError):
            pass
        finally:
            # Whatever ends the reader ends the session: it never outlives its client's input.
            self._queue.put(_EOF)
            self._raise_restart()

    def _raise_restart(self) -> None:
        self._restart.set()
        self.restart_flag[0] = 1

    def restart_pending(self) -> bool:
        """Whether a command that makes the current image obsolete is waiting (cheap: the
        renderer checks it before every bounce)."""
        return self._restart.is_set()

    def take(self, block: bool) -> list:
        """Every waiting entry (blocking for the first one if ``block``); END marks end of input."""
        items = []
        try:
            items.append(self._queue.get(block=block))
        except queue.Empty:
            return items
        self._restart.clear()
        self.restart_flag[0] = 0
        while True:
            try:
                items.append(self._queue.get_nowait())
            except queue.Empty:
                break
        return [END if item is _EOF else item for item in items]


class _End:
    def __repr__(self):
        return "END"


END = _End()
