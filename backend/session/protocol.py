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

from ..errors import LaminaError

PROTOCOL = 1
SECTIONS = ("film", "camera", "render", "materials", "meshes", "objects", "lights", "world")
MERGED_SECTIONS = ("materials", "meshes")
COMMANDS = ("scene", "update", "samples", "ping", "stop")
#: Commands after which the current image is out of date (the render loop abandons its work).
RESTARTING = ("scene", "update", "stop")


class ProtocolError(LaminaError):
    """A command the session cannot understand (reported, then ignored)."""


def _generation(msg: dict) -> int:
    g = msg.get("generation")
    if isinstance(g, bool) or not isinstance(g, int) or g < 0:
        raise ProtocolError(f"{msg['cmd']}: 'generation' must be an integer >= 0, got {g!r}")
    return g


def _read_json_file(path, what: str):
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ProtocolError(f"{what}: cannot read {path}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ProtocolError(f"{what}: {path} is not valid JSON: {exc}") from None


def parse_command(line: str) -> dict:
    """A validated command: ``{"cmd": ...}`` with its fields (files named by the command are
    read here, so the render loop gets the data)."""
    try:
        msg = json.loads(line)
    except json.JSONDecodeError as exc:
        raise ProtocolError(f"not a JSON command: {exc.msg} (column {exc.colno}): {line[:80]!r}") from None
    if not isinstance(msg, dict):
        raise ProtocolError(f"a command must be a JSON object, got {line[:80]!r}")
    cmd = msg.get("cmd")
    if cmd not in COMMANDS:
        raise ProtocolError(f"unknown command {cmd!r} (known: {', '.join(COMMANDS)})")
    if cmd == "scene":
        _generation(msg)
        if "path" in msg:
            path = Path(str(msg["path"]))
            msg["scene"] = _read_json_file(path, "scene")
            msg.setdefault("base", str(path.parent))
            msg["where"] = str(path)
        elif not isinstance(msg.get("scene"), dict):
            raise ProtocolError("scene: give 'path' (a scene file) or 'scene' (the document)")
        else:
            msg.setdefault("where", "<session scene>")
    elif cmd == "update":
        _generation(msg)
        if "changes_file" in msg:
            msg["changes"] = _read_json_file(msg["changes_file"], "update")
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
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ProtocolError(f"samples: 'samples' must be an integer >= 0 (0 = no limit), got {n!r}")
    return msg


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
        self._stream = stream if stream is not None else sys.stdin
        self._thread = threading.Thread(target=self._read, name="lamina-session-stdin", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        try:
            for line in self._stream:
                line = line.strip()
                if not line:
                    continue
                try:
                    item = parse_command(line)
                except ProtocolError as exc:
                    item = exc
                # Queued before the flag is raised: a raised flag always has its command waiting
                # (a flag raised for a command already taken only costs one empty look).
                self._queue.put(item)
                if isinstance(item, dict) and item["cmd"] in RESTARTING:
                    self._restart.set()
        except (OSError, ValueError):
            pass
        self._queue.put(_EOF)
        self._restart.set()

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
