"""The backend as a child process: start, read its JSON progress lines, cancel, clean up.

No bpy here (tested on its own). The child is ``<python> -m backend render ... --progress json``
(docs/cli.md) with ``PYTHONPATH`` naming the extension folder (for ``backend``) and the folders
the parent found numpy, embreex, OpenImageIO, numba and llvmlite in — Blender's Python does not
search the extensions' wheel folder by itself. The child gets its own process group, so cancelling can end
it *and* its worker processes: a polite SIGTERM first (the backend writes what is done), then
SIGKILL to the whole group after a short grace period. No orphan survives a cancel.

No Python threads: Blender does not support them (they crash it in hard-to-trace ways while the UI
or an operator runs; the preset thumbnails crashed the tests that way). The child writes its
stdout and stderr to two temporary files, which ``poll`` reads from where it stopped last time
(a file never fills up and blocks the child the way an unread pipe does, and this works the same
on Windows, where pipes cannot be polled).
"""
from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EXTENSION_ROOT = Path(__file__).resolve().parent.parent.parent   # holds backend/
DEPENDENCIES = ("numpy", "embreex", "OpenImageIO", "numba", "llvmlite")
GRACE_SECONDS = 1.0      # after SIGTERM, before the process group is killed
POLL_STEP = 0.02         # seconds between reads of the output files while poll() waits
STDERR_LINES = 200       # the tail of stderr kept for failure messages


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


class _OutputFile:
    """A temporary file the child writes one stream to; ``lines()`` returns the complete lines
    added since the last call (the unterminated end waits for its newline, or for ``final``)."""

    def __init__(self, name: str):
        fd, self.path = tempfile.mkstemp(prefix=f"lamina-{name}-", suffix=".log")
        self.child_fd = fd                       # handed to the child, closed here after start
        self._reader = open(self.path, "rb")
        self._rest = b""

    def lines(self, final: bool = False) -> list[str]:
        if self._reader is None:
            return []
        data = self._rest + self._reader.read()
        parts = data.split(b"\n")
        self._rest = parts.pop()
        if final and self._rest:
            parts.append(self._rest)
            self._rest = b""
        return [p.decode("utf-8", "replace").rstrip("\r") for p in parts]

    @property
    def is_open(self) -> bool:
        return self._reader is not None

    def close_child_end(self) -> None:
        if self.child_fd is not None:
            os.close(self.child_fd)
            self.child_fd = None

    def close(self) -> None:
        self.close_child_end()
        if self._reader is not None:
            self._reader.close()
            self._reader = None
        try:
            os.unlink(self.path)
        except OSError:
            pass


class BackendJob:
    """One running backend process. ``poll()`` returns the JSON events that arrived."""

    def __init__(self, cmd: list[str], *, env: dict | None = None, cwd: str | None = None,
                 stdin_pipe: bool = False):
        kwargs = {}
        if sys.platform == "win32":
            kwargs["creationflags"] = subprocess.CREATE_NEW_PROCESS_GROUP
        else:
            kwargs["start_new_session"] = True           # own process group for killpg
        self.cmd = cmd
        self.started = time.perf_counter()
        self._out, self._err = _OutputFile("out"), _OutputFile("err")
        try:
            self.proc = subprocess.Popen(cmd, stdout=self._out.child_fd, stderr=self._err.child_fd,
                                         stdin=subprocess.PIPE if stdin_pipe else subprocess.DEVNULL,
                                         env=env, cwd=cwd, **kwargs)
        except BaseException:
            self._out.close()
            self._err.close()
            raise
        self._out.close_child_end()                     # the child has its own copies
        self._err.close_child_end()
        self.pgid = self.proc.pid if sys.platform != "win32" else None
        self._pending: list[dict] = []
        self._stderr: list[str] = []
        self.cancelled = False

    # -- writing (a session's commands; only with stdin_pipe)

    def send(self, line: str) -> bool:
        """Write one line to the child's stdin. False if the child cannot take it any more
        (exited, or its end of the pipe is closed). The child reads its stdin all the time,
        so a line never waits for long; big payloads go through files (docs/session.md)."""
        stdin = self.proc.stdin
        if stdin is None or stdin.closed or self._exited():
            return False
        try:
            stdin.write(line.encode("utf-8") + b"\n")
            stdin.flush()
        except (BrokenPipeError, OSError, ValueError):
            return False
        return True

    def close_stdin(self) -> None:
        """End of input: a session then ends by itself."""
        stdin = self.proc.stdin
        if stdin is not None and not stdin.closed:
            try:
                stdin.close()
            except OSError:
                pass

    # -- reading

    def _read(self, final: bool = False) -> None:
        for line in self._out.lines(final):
            line = line.strip()
            if not line:
                continue
            try:
                event = json.loads(line)
            except json.JSONDecodeError:
                event = {"event": "log", "message": line}
            if not isinstance(event, dict):
                event = {"event": "log", "message": line}
            self._pending.append(event)
        err = self._err.lines(final)
        if err:
            self._stderr.extend(err)
            del self._stderr[:-STDERR_LINES]

    def poll(self, timeout: float = 0.1) -> list[dict]:
        """The events that arrived, waiting up to ``timeout`` seconds for the first one."""
        deadline = time.monotonic() + timeout
        while True:
            self._read()
            if self._pending or time.monotonic() >= deadline or self._exited():
                events, self._pending = self._pending, []
                return events
            time.sleep(min(POLL_STEP, max(deadline - time.monotonic(), 0.0)))

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
        """The process ended and everything it printed has been returned by ``poll``. (Workers a
        crashed child left behind do not hold this up: ``wait`` kills them.)"""
        if not self._exited():
            return False
        self._read(final=True)
        return not self._pending

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
        self.close_stdin()
        if self.proc.returncode is not None and self._out.is_open:
            self._read(final=True)                   # the last words, then the files go
            self._out.close()
            self._err.close()

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
