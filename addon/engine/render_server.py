"""Warm renderer processes for F12, animation frames and material previews.

No bpy here (tested on its own). ``python -m backend render`` in a new process spends most of a
small render starting: the interpreter, NumPy, Numba, embree and the compiled kernels. A render
server (``python -m backend serve``, backend/cli/serve.py) pays that once and then renders job
after job. This module keeps up to one server per *purpose* ("final": F12 and animation frames;
"preview": material previews, which Blender may render while a final render runs) and hands out
``ServerJob``s, which look like ``job.BackendJob`` to the engine (poll, finished, wait, cancel,
kill_group, failure_message), so the engine's event loop is the same for both.

A server is replaced when it died, when the Python or environment the engine asks for changed
(the preferences), or never shared: a purpose whose server is busy gets ``None`` and the engine
starts a one-off ``render`` process as before. A cancel is a command (the server writes what is
done and stays); a server that does not answer it within the grace period is killed with its
whole process group, and the next render starts a new one.
"""
from __future__ import annotations

import json
import time

from .job import BackendJob

CANCEL_GRACE = 3.0         # seconds a cancelled job may take to end before the server is killed
#: Jobs a server renders before the pool replaces it (between two jobs): the files its output goes
#: through (job.py) only grow, by ~100 kB a render's progress events, and a process that lives
#: for a whole animation should not carry them (or anything else a render leaves) forever.
JOBS_PER_SERVER = 100


def serve_command(python: str) -> list[str]:
    return [python, "-m", "backend", "serve", "--warm"]


class RenderServer:
    def __init__(self, python: str, env: dict | None, *, job=None):
        self.key = (python, tuple(sorted((env or {}).items())))
        # ``job``: a stand-in with BackendJob's interface (tests).
        self.job = job if job is not None else BackendJob(serve_command(python), env=env, stdin_pipe=True)
        self.current: ServerJob | None = None
        self.jobs_done = 0
        self._count = 0

    @property
    def alive(self) -> bool:
        return self.job.running

    @property
    def busy(self) -> bool:
        return self.current is not None and not self.current.done

    def submit(self, args: list[str]) -> "ServerJob":
        """Send one render (the ``render`` sub-command's arguments) and return its job."""
        self._count += 1
        job = ServerJob(self, f"{self.job.proc.pid}-{self._count}")
        self.current = job
        if not self.job.send(json.dumps({"cmd": "render", "job": job.id, "args": list(args)})):
            job._server_gone()
        return job

    def pump(self, timeout: float) -> None:
        """Read the server's events and hand them to the job in progress."""
        for event in self.job.poll(timeout):
            kind = event.get("event")
            job = self.current
            if job is None or job.done:
                continue
            owner = event.get("job")
            if owner is None and kind in ("compiling", "compiled", "warning", "error", "log"):
                job.pending.append(event)            # the server's own start, seen by its first job
            elif owner == job.id:
                if kind == "exit":
                    job._exit(int(event.get("status", 1)), event.get("message"))
                else:
                    job.pending.append(event)
        if self.current is not None and not self.current.done and not self.job.running:
            self.current._server_gone()

    def stop(self) -> None:
        if self.job.running:
            self.job.send(json.dumps({"cmd": "stop"}))
            self.job.close_stdin()
            deadline = time.monotonic() + 1.0
            while self.job.running and time.monotonic() < deadline:
                time.sleep(0.01)
        self.job.kill_group()


class ServerJob:
    """One render in a server; the interface of job.BackendJob that the engine uses."""

    def __init__(self, server: RenderServer, job_id: str):
        self.server = server
        self.id = job_id
        self.pending: list[dict] = []
        self.done = False
        self.status: int | None = None
        self.message: str | None = None
        self.cancelled = False

    # -- what the server said

    def _exit(self, status: int, message) -> None:
        self.done, self.status, self.message = True, status, message
        self.server.jobs_done += 1

    def _server_gone(self) -> None:
        if self.done:
            return
        self.server.job.kill_group()
        code = self.server.job.returncode
        self.done = True
        self.status = 1 if code in (None, 0) else code
        self.message = (f"the renderer process ended unexpectedly (signal {-code})" if code is not None and code < 0
                        else self.server.job.failure_message())

    # -- BackendJob's interface

    def poll(self, timeout: float = 0.1) -> list[dict]:
        if not self.pending and not self.done:
            self.server.pump(timeout)
        events, self.pending = self.pending, []
        return events

    def finished(self) -> bool:
        return self.done and not self.pending

    @property
    def running(self) -> bool:
        return not self.done

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self.done:
            if deadline is not None and time.monotonic() >= deadline:
                raise TimeoutError(f"render job {self.id} did not end within {timeout} s")
            self.server.pump(0.05)
        return int(self.status)

    @property
    def returncode(self):
        return self.status

    def failure_message(self) -> str:
        if self.message:
            return str(self.message)
        for event in reversed(self.pending):
            if event.get("event") == "error":
                return str(event.get("message"))
        return f"the renderer exited with status {self.status}"

    def stderr_text(self) -> str:
        return self.server.job.stderr_text()

    def cancel(self, grace: float = CANCEL_GRACE) -> None:
        """Stop this render (the server writes what is done and stays); a server that does not
        end the job within ``grace`` seconds is killed with its process group."""
        self.cancelled = True
        if self.done:
            return
        self.server.job.send(json.dumps({"cmd": "cancel", "job": self.id}))
        deadline = time.monotonic() + grace
        while not self.done and time.monotonic() < deadline:
            self.server.pump(0.05)
        if not self.done:
            self.server.job.kill_group()
            self._server_gone()

    def kill_group(self) -> None:
        """The engine's 'no orphan, whatever happened': a job still running is cancelled; a
        finished one leaves its server warm for the next render."""
        if not self.done:
            self.cancel()


class ServerPool:
    """At most one server per purpose; ``job_for`` starts one or returns None (then the caller
    renders in a one-off process)."""

    def __init__(self, factory=RenderServer):
        self.factory = factory
        self.servers: dict[str, RenderServer] = {}

    def _server(self, purpose: str, python: str, env: dict | None) -> RenderServer | None:
        """The purpose's idle server, started or replaced as needed; None while it is busy."""
        server = self.servers.get(purpose)
        key = (python, tuple(sorted((env or {}).items())))
        if server is not None and server.busy:
            return None
        if server is not None and (not server.alive or server.key != key or server.jobs_done >= JOBS_PER_SERVER):
            server.stop()
            server = None
        if server is None:
            server = self.servers[purpose] = self.factory(python, env)
        return server

    def job_for(self, purpose: str, python: str, env: dict | None, args: list[str]) -> ServerJob | None:
        server = self._server(purpose, python, env)
        return server.submit(args) if server is not None else None

    def prestart(self, purpose: str, python: str, env: dict | None) -> None:
        """Start the purpose's server now, ahead of its first job (Blender's UI does this for
        material previews once the kernels are compiled: the first thumbnail finds it loaded)."""
        self._server(purpose, python, env)

    def stop_all(self) -> None:
        for server in list(self.servers.values()):
            try:
                server.stop()
            except Exception:  # noqa: BLE001 - interpreter shutdown
                pass
        self.servers.clear()


POOL = ServerPool()
