"""The backend as a child process: start, read its JSON progress lines, cancel, clean up.

No bpy here (tested on its own). The child is ``<python> -m backend render ... --progress json``
(docs/cli.md) with ``PYTHONPATH`` naming the extension folder (for ``backend``) and the folders
the parent found numpy, embreex and OpenImageIO in — Blender's Python does not search the
extensions' wheel folder by itself. The child gets its own process group, so cancelling can end
it *and* its worker processes: a polite SIGTERM first (the backend writes what is done), then
SIGKILL to the whole group after a short grace period. No orphan survives a cancel.
"""
from __future__ import annotations

import importlib.util
import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

EXTENSION_ROOT = Path(__file__).resolve().parent.parent.parent   # holds backend/
DEPENDENCIES = ("numpy", "embreex", "OpenImageIO")
GRACE_SECONDS = 1.0      # after SIGTERM, before the process group is killed
STRAY_SECONDS = 2.0      # after the child exited, before processes it left behind are killed


def dependency_paths() -> list[str]:
    """Folders that hold the backend's dependencies as the parent process sees them."""
    out: list[str] = []
    for name in DEPENDENCIES:
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            spec = None
        if spec is None or not spec.origin:
            continue
        origin = Path(spec.origin)
        # A package's origin is <dir>/<name>/__init__.py; a module's is <dir>/<name>.so.
        folder = origin.parent.parent if origin.name.startswith("__init__") else origin.parent
        if str(folder) not in out:
            out.append(str(folder))
    return out


def child_environment(extra: dict | None = None) -> dict:
    env = dict(os.environ)
    paths = [str(EXTENSION_ROOT), *dependency_paths()]
    if env.get("PYTHONPATH"):
        paths.append(env["PYTHONPATH"])
    env["PYTHONPATH"] = os.pathsep.join(paths)
    env["PYTHONUNBUFFERED"] = "1"
    if extra:
        env.update(extra)
    return env


def render_command(python: str, scene: Path, output: Path, partial: Path, *, workers: int = 0,
                   partial_interval: float = 2.0, extra: list[str] | None = None) -> list[str]:
    cmd = [python, "-m", "backend", "render", str(scene), "-o", str(output),
           "--progress", "json", "--partial", str(partial),
           "--partial-interval", f"{partial_interval:g}"]
    if workers > 0:
        cmd += ["--workers", str(workers)]
    return cmd + list(extra or [])


class BackendJob:
    """One running backend process. ``poll()`` returns the JSON events that arrived."""

    def __init__(self, cmd: list[str], *, env: dict | None = None, cwd: str | None = None):
        kwargs = {}
        if sys.platform == "win32":
            kwargs["creationflags"] = subprocess.CREATE_NEW_PROCESS_GROUP
        else:
            kwargs["start_new_session"] = True           # own process group for killpg
        self.cmd = cmd
        self.started = time.perf_counter()
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     stdin=subprocess.DEVNULL, env=env, cwd=cwd, **kwargs)
        self.pgid = self.proc.pid if sys.platform != "win32" else None
        self._events: queue.Queue = queue.Queue()
        self._stderr: list[str] = []
        self.cancelled = False
        self._exit_seen = None
        self._threads = [threading.Thread(target=self._read_stdout, daemon=True),
                         threading.Thread(target=self._read_stderr, daemon=True)]
        for t in self._threads:
            t.start()

    # -- reading (threads: pipes cannot be polled portably, and a full pipe would block the child)

    def _read_stdout(self) -> None:
        for raw in self.proc.stdout:
            line = raw.decode("utf-8", "replace").strip()
            if not line:
                continue
            try:
                event = json.loads(line)
            except json.JSONDecodeError:
                event = {"event": "log", "message": line}
            if not isinstance(event, dict):
                event = {"event": "log", "message": line}
            self._events.put(event)
        self.proc.stdout.close()

    def _read_stderr(self) -> None:
        for raw in self.proc.stderr:
            self._stderr.append(raw.decode("utf-8", "replace").rstrip())
            del self._stderr[:-200]
        self.proc.stderr.close()

    def poll(self, timeout: float = 0.1) -> list[dict]:
        events = []
        try:
            events.append(self._events.get(timeout=timeout))
            while True:
                events.append(self._events.get_nowait())
        except queue.Empty:
            pass
        return events

    def _exited(self) -> bool:
        """Whether the child has exited, *without reaping it* where the OS allows: an unreaped
        child keeps its PID — our process-group id — reserved, so a later killpg can never hit
        an unrelated group that reused the number."""
        if self.proc.returncode is not None:
            return True
        if hasattr(os, "waitid") and sys.platform != "win32":
            try:
                info = os.waitid(os.P_PID, self.proc.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
            except ChildProcessError:
                return self.proc.poll() is not None
            return info is not None
        return self.proc.poll() is not None

    @property
    def running(self) -> bool:
        return not self._exited()

    def finished(self) -> bool:
        """The process ended and everything it printed has been read."""
        if not self._exited():
            return False
        if self._exit_seen is None:
            self._exit_seen = time.monotonic()
        readers_alive = any(t.is_alive() for t in self._threads)
        if readers_alive and time.monotonic() - self._exit_seen > STRAY_SECONDS:
            self.kill_group()        # stray workers of a crashed child hold the pipes open
            readers_alive = any(t.is_alive() for t in self._threads)
        return not readers_alive and self._events.empty()

    def wait(self, timeout: float | None = None) -> int:
        """Wait for the child to exit, end whatever is left of its group, reap it."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self._exited():
            if deadline is not None and time.monotonic() >= deadline:
                raise subprocess.TimeoutExpired(self.cmd, timeout)
            time.sleep(0.02)
        self.kill_group()
        return self.proc.returncode

    @property
    def returncode(self):
        return self.proc.returncode

    def stderr_text(self) -> str:
        return "\n".join(self._stderr)

    def failure_message(self) -> str:
        """The most useful line of a failed run: the backend's 'error: ...' or a traceback's end."""
        lines = [l for l in self._stderr if l.strip()]
        for line in reversed(lines):
            if line.startswith("error:"):
                return line[len("error:"):].strip()
        if lines:
            return lines[-1].strip()
        return f"the renderer exited with status {self.proc.returncode}"

    # -- stopping

    def cancel(self, grace: float = GRACE_SECONDS) -> None:
        """Stop the render: SIGTERM (writes what is done), then kill the whole process group."""
        self.cancelled = True
        if not self._exited():
            try:
                if sys.platform == "win32":
                    self.proc.send_signal(signal.CTRL_BREAK_EVENT)
                else:
                    self.proc.terminate()
            except OSError:
                pass
            deadline = time.monotonic() + grace
            while not self._exited() and time.monotonic() < deadline:
                time.sleep(0.02)
        self.kill_group()

    def kill_group(self) -> None:
        """Kill every process of the child's group (the child and its workers), then reap."""
        if sys.platform == "win32":
            if self.proc.poll() is None:       # Popen's handle keeps the PID from being reused
                subprocess.run(["taskkill", "/F", "/T", "/PID", str(self.proc.pid)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        elif self.proc.returncode is None:     # not reaped yet: the group id is still ours
            try:
                os.killpg(self.pgid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            pass
        for t in self._threads:
            t.join(timeout=2)

    def group_alive(self) -> bool:
        """Whether any process of the child's group still exists (POSIX; tests use it)."""
        if self.pgid is None:
            return self.proc.poll() is None
        try:
            os.killpg(self.pgid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True
