"""The client side of a renderer session (``python -m backend session``, docs/session.md).

No bpy here (tested on its own). A ``SessionClient`` starts the session process (``job.py``:
own process group, stdout/stderr to files read on the main thread, no Python threads), sends the
scene and edits, each with a new *generation*, reads events, and hands out the newest frame.

Stale frames: the client remembers the generation of its last edit and only ever returns a frame
of that generation — a frame rendered before an edit is never returned after the edit was sent,
whatever order files and events arrive in. ``answered`` tells whether the session has shown
anything (a frame) or failed for the last edit; the viewport paces its edits with it.
"""
from __future__ import annotations

import json
import os
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .job import BackendJob

# The frame file header (docs/session.md; backend/session/frames.py writes it).
FRAME_MAGIC = b"LAMFRAME"
FRAME_HEADER = struct.Struct("<8sIIQQIIIIII8x")
FRAME_FINAL = 1
INLINE_LIMIT = 32 * 1024      # bytes: bigger updates travel through a file
STOP_GRACE = 1.0              # seconds a stopping session may take before its group is killed


@dataclass
class Frame:
    frame: int
    generation: int
    width: int
    height: int
    spp: int
    scale: int
    final: bool
    pixels: np.ndarray = field(repr=False)       # (height, width, 4) float32, row 0 at the top
    #: A final frame's denoising features (height, width, 6: albedo, normal), when the session
    #: wrote them (docs/session.md, feature files); None otherwise.
    features: np.ndarray | None = field(default=None, repr=False)


def read_frame_file(path, channels: int = 4) -> Frame | None:
    """The frame in ``path``, or None if it is missing, incomplete or not a frame file (of
    ``channels`` channels: 4 for a frame, 6 for a feature file)."""
    try:
        data = Path(path).read_bytes()
    except OSError:
        return None
    if len(data) < FRAME_HEADER.size:
        return None
    magic, version, size, frame, generation, w, h, c, spp, scale, flags = FRAME_HEADER.unpack_from(data)
    if magic != FRAME_MAGIC or version != 1 or size != FRAME_HEADER.size or c != channels:
        return None
    n = w * h * c
    if len(data) < size + 4 * n:
        return None
    pixels = np.frombuffer(data, dtype="<f4", count=n, offset=size).reshape(h, w, c)
    return Frame(frame, generation, w, h, spp, scale, bool(flags & FRAME_FINAL), pixels)


def session_command(python: str, frames: Path, *, samples: int, workers: int = 0, warm: bool = False) -> list[str]:
    cmd = [python, "-m", "backend", "session", "--frames", str(frames), "--samples", str(int(samples))]
    if workers > 0:
        cmd += ["--workers", str(int(workers))]
    if warm:
        cmd.append("--warm")
    return cmd


class SessionClient:
    def __init__(self, cmd: list[str], folder: Path, *, env: dict | None = None, job=None):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.cmd = cmd
        # ``job``: a stand-in with BackendJob's interface (tests).
        self.job = job if job is not None else BackendJob(cmd, env=env, stdin_pipe=True)
        self.pid = self.job.proc.pid
        self.started = time.perf_counter()
        self.generation = 0            # of the last scene/edit sent (0 = none yet)
        self.sent_at = 0.0
        self.ready = False
        self.warm = False
        self.compiling = False
        self.stopping = False
        self.error: str | None = None  # fatal: the session is gone
        self.scene_error: str | None = None   # the last edit could not be applied (session alive)
        self.warnings: list[str] = []
        self.answered = 0              # newest generation with a frame or an error
        self.idle = False              # the sample target of the current generation is reached
        self.spp = 0
        self.last_updated: dict | None = None
        self.stale_frames = 0          # frame events dropped because an edit came after them
        self._frame_event: dict | None = None
        self._frame_number = 0         # newest frame handed out
        self._update_files = 0

    # ------------------------------------------------------------------ sending

    def _send(self, message: dict) -> None:
        if not self.job.send(json.dumps(message, allow_nan=False)):
            self._check_exit()
            if self.error is None:
                self.error = "the viewport renderer stopped reading its commands"

    def _next_generation(self) -> int:
        self.generation += 1
        self.sent_at = time.perf_counter()
        self.idle = False
        self.spp = 0
        self.scene_error = None
        self._frame_event = None
        return self.generation

    def send_scene(self, path: Path) -> int:
        g = self._next_generation()
        self._send({"cmd": "scene", "generation": g, "path": str(path)})
        return g

    def send_update(self, changes: dict) -> int:
        g = self._next_generation()
        text = json.dumps(changes, allow_nan=False)
        if len(text) > INLINE_LIMIT:
            self._update_files += 1
            path = self.folder / f"update-{self._update_files % 4}.json"
            tmp = path.with_suffix(".tmp")
            tmp.write_text(text, encoding="utf-8")
            os.replace(tmp, path)
            self._send({"cmd": "update", "generation": g, "changes_file": str(path)})
        else:
            self._send({"cmd": "update", "generation": g, "changes": changes})
        return g

    def set_samples(self, samples: int) -> None:
        self._send({"cmd": "samples", "samples": int(samples)})
        if samples == 0 or samples > self.spp:
            self.idle = False

    # ------------------------------------------------------------------ receiving

    def poll(self) -> list[dict]:
        """Read what the session said since the last call; returns the events."""
        events = self.job.poll(0.0)
        for event in events:
            kind = event.get("event")
            g = event.get("generation")
            if kind == "ready":
                self.ready = True
                self.compiling = False
            elif kind == "compiling":
                self.compiling = True
            elif kind == "warm":
                self.warm = True
            elif kind == "updated":
                if g == self.generation:
                    self.last_updated = event
            elif kind == "frame":
                if g is not None and g >= self.generation:
                    self._frame_event = event
                    self.answered = max(self.answered, g)
                    self.spp = int(event.get("spp", 0))
                else:
                    self.stale_frames += 1
            elif kind == "idle":
                if g == self.generation:
                    self.idle = True
            elif kind == "warning":
                message = str(event.get("message", ""))
                if message and message not in self.warnings:
                    self.warnings.append(message)
            elif kind == "error":
                message = str(event.get("message", "the viewport renderer failed"))
                if event.get("fatal"):
                    self.error = message
                elif g is None or g >= self.generation:
                    self.scene_error = message
                    if g is not None:
                        self.answered = max(self.answered, g)
                else:
                    pass                      # about an edit that was superseded since
        self._check_exit()
        return events

    def _check_exit(self) -> None:
        if self.error is None and not self.stopping and not self.job.running:
            code = self.job.proc.poll()
            self.error = self.job.failure_message() if code != 0 else "the viewport renderer exited"
            if code is not None and code < 0:
                self.error = f"the viewport renderer process ended unexpectedly (signal {-code})"

    @property
    def frame_waiting(self) -> bool:
        return self._frame_event is not None and self._frame_event.get("frame", 0) > self._frame_number

    def take_frame(self) -> Frame | None:
        """The newest frame of the current generation not handed out yet, or None. A frame file
        that holds an older generation than the last edit is refused (never shown)."""
        event = self._frame_event
        if event is None or event.get("frame", 0) <= self._frame_number:
            return None
        frame = read_frame_file(event.get("path", ""))
        if frame is None or frame.generation < self.generation or frame.frame < event.get("frame", 0):
            # The slot was overwritten by an older frame (impossible with one writer) or the file
            # is gone: wait for the next event.
            self._frame_event = None
            return None
        self._frame_number = frame.frame
        self._frame_event = None
        if frame.final and event.get("features"):
            features = read_frame_file(event["features"], channels=6)
            # Only the features of this very frame (a slot may already hold a newer one).
            if features is not None and features.frame == frame.frame and \
                    features.pixels.shape[:2] == frame.pixels.shape[:2]:
                frame.features = features.pixels
        return frame

    # ------------------------------------------------------------------ ending

    @property
    def alive(self) -> bool:
        return self.job.running

    def stop(self, grace: float = STOP_GRACE) -> None:
        """Ask the session to end (``stop``, then end of input), then make sure its whole
        process group is gone. Idempotent."""
        if self.stopping and not self.job.running:
            self.job.kill_group()
            return
        self.stopping = True
        if self.job.running:
            self.job.send(json.dumps({"cmd": "stop"}))
            self.job.close_stdin()
            deadline = time.monotonic() + grace
            while self.job.running and time.monotonic() < deadline:
                time.sleep(0.01)
        self.job.kill_group()

    def kill(self) -> None:
        """End the process group at once (interpreter exit, add-on disabled)."""
        self.stopping = True
        self.job.kill_group()
