"""``serve`` sub-command: a render server, one warm process for many ``render`` jobs
(docs/cli.md, "The render server").

Every ``python -m backend render`` starts an interpreter, imports NumPy, Numba and embree and
loads the compiled kernels before its first sample: 1.5–3 s that a small F12 render or a material
preview pays each time. The server pays them once. Blender's engine keeps one running
(addon/engine/render_server.py) and sends it each F12, animation frame and material preview.

Protocol (JSON lines; stdin commands, stdout events, like the session's, docs/session.md):

* ``{"cmd": "render", "job": ID, "args": [...]}`` — ``args`` are the ``render`` sub-command's
  arguments (one scene file; ``--progress`` is always json). Every event ``render --progress
  json`` writes follows with ``"job": ID`` added, and last ``{"event": "exit", "job": ID,
  "status": S}`` (S: render's exit status; with ``"message"`` when it failed). Jobs run one
  after the other, in the order sent.
* ``{"cmd": "cancel", "job": ID}`` — stop that job as SIGTERM stops ``render``: what is done is
  written, ``exit`` follows with status 130. A cancel for a job not started yet drops it.
* ``{"cmd": "ping"}`` → ``{"event": "pong"}``; ``{"cmd": "stop"}`` or the end of stdin: the server
  ends after the job in progress.

Events before the first job: ``compiling``/``compiled`` on a cold kernel cache (as ``render``'s),
then ``ready`` (``protocol``, ``pid``), then with ``--warm`` ``warm`` (``seconds``) once every kernel
is loaded. A job's failure is its ``exit`` event; the server carries on. stderr is for people.
"""
from __future__ import annotations

import contextlib
import io
import json
import os
import queue
import sys
import threading
import traceback

PROTOCOL = 1


def register(sub) -> None:
    p = sub.add_parser("serve", help="render server: one warm process for many render jobs "
                                     "(JSON commands on stdin, events on stdout; docs/cli.md)")
    p.add_argument("--warm", action="store_true",
                   help="load every compiled kernel before the first job arrives")
    p.set_defaults(func=cmd_serve)


class _Events:
    """JSON lines on stdout, one writer at a time (the reader thread answers pings)."""

    def __init__(self, stream=None):
        self.stream = stream if stream is not None else sys.stdout
        self.lock = threading.Lock()

    def __call__(self, event: dict) -> None:
        line = json.dumps(event, allow_nan=False, default=str) + "\n"
        with self.lock:
            self.stream.write(line)
            self.stream.flush()


class _JobPrinter:
    """render_one.ProgressPrinter's interface in json mode, each event tagged with its job."""
    mode = "json"

    def __init__(self, events: _Events, job):
        self.events = events
        self.job = job

    def emit(self, event: dict) -> None:
        self.events({**event, "job": self.job})


class Server:
    def __init__(self, events: _Events, stdin=None):
        self.events = events
        self.stdin = stdin if stdin is not None else sys.stdin
        self.jobs: queue.Queue = queue.Queue()
        self.lock = threading.Lock()
        self.current = None            # the job id in progress
        self.renderer = None           # its Renderer, once it exists
        self.cancelled: set = set()    # job ids cancelled (before or while they run)
        threading.Thread(target=self._read, name="lamina-serve-stdin", daemon=True).start()

    # -- the reader thread: commands in; cancels and pings answered at once

    def _read(self) -> None:
        for line in self.stdin:
            line = line.strip()
            if not line:
                continue
            try:
                command = json.loads(line)
                if not isinstance(command, dict):
                    raise ValueError("not an object")
            except ValueError as exc:
                self.events({"event": "warning", "message": f"unreadable command ignored ({exc}): {line[:200]}"})
                continue
            kind = command.get("cmd")
            if kind == "render":
                self.jobs.put(command)
            elif kind == "cancel":
                self._cancel(command.get("job"))
            elif kind == "ping":
                self.events({"event": "pong"})
            elif kind == "stop":
                break
            else:
                self.events({"event": "warning", "message": f"unknown command ignored: {kind!r}"})
        self.jobs.put(None)

    def _cancel(self, job) -> None:
        with self.lock:
            self.cancelled.add(job)
            if job == self.current and self.renderer is not None:
                self.renderer.request_stop()

    def _on_renderer(self, renderer) -> None:
        with self.lock:
            self.renderer = renderer
            if self.current in self.cancelled:
                renderer.request_stop()

    # -- the main thread: one job at a time

    def run(self) -> int:
        while True:
            command = self.jobs.get()
            if command is None:
                return 0
            job = command.get("job")
            with self.lock:
                if job in self.cancelled:
                    self.cancelled.discard(job)
                    skip = True
                else:
                    self.current, self.renderer, skip = job, None, False
            if skip:
                self.events({"event": "exit", "job": job, "status": 130, "message": "cancelled before it started"})
                continue
            status, message = self._render(job, command.get("args"))
            with self.lock:
                self.current, self.renderer = None, None
                self.cancelled.discard(job)
            out = {"event": "exit", "job": job, "status": status}
            if message:
                out["message"] = message
            self.events(out)

    def _render(self, job, argv) -> tuple[int, str | None]:
        from ..errors import OUT_OF_MEMORY, LaminaError
        from ..scene.reader import MISSING_TEXTURES
        from . import build_parser
        from .render import render_job
        if not isinstance(argv, list) or not all(isinstance(a, str) for a in argv):
            return 2, "'args' must be a list of strings (the render command's arguments)"
        usage = io.StringIO()
        try:
            with contextlib.redirect_stderr(usage):
                args = build_parser().parse_args(["render", *argv])
        except SystemExit:
            lines = [l for l in usage.getvalue().splitlines() if l.strip()]
            return 2, lines[-1] if lines else "bad render arguments"
        if len(args.scene) != 1:
            return 2, "the render server renders one scene per job (send one job per frame)"
        args.progress = "json"
        printer = _JobPrinter(self.events, job)
        token = MISSING_TEXTURES.set(None)
        try:
            return render_job(args, printer, on_renderer=self._on_renderer), None
        except LaminaError as exc:
            return 2, str(exc)
        except MemoryError:
            return 2, OUT_OF_MEMORY
        except Exception as exc:  # noqa: BLE001 - one job's failure must not end the server
            traceback.print_exc()
            return 1, f"internal error: {type(exc).__name__}: {exc}"
        finally:
            MISSING_TEXTURES.reset(token)


def cmd_serve(args) -> int:
    import signal

    from ..warmup import ensure_compiled, load_kernels
    # SIGTERM ends the process at once (a job's client cancels with the cancel command).
    try:
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    except (ValueError, OSError):
        pass
    events = _Events()
    server = Server(events)          # reads commands from now on; they wait for ``ready``
    ensure_compiled(events)
    events({"event": "ready", "protocol": PROTOCOL, "pid": os.getpid()})
    if args.warm:
        events({"event": "warm", "seconds": round(load_kernels(), 3)})
    return server.run()
