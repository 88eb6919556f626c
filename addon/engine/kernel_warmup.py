"""Compile the render kernels in the background, so the first F12 finds a warm cache.

The first render after installing or updating Lamina compiles its kernels (about a minute; the
render would sit on "Compiling" meanwhile). This module runs ``python -m backend warmup`` (
backend/cli/warmup.py) as a child process instead: from the Preferences button *Compile Render
Kernels*, and once by itself a few seconds after the extension is enabled in the UI. On a warm
cache the child says so and exits in about a second. Under ``blender -b`` nothing starts by
itself: a farm node's first render compiles and prints the two lines, or the farm runs
``python -m backend warmup`` once (docs/cli.md).

No Python thread (Blender does not support them, see job.py): a ``bpy.app.timers`` tick polls
the child's JSON lines. ``state()`` is what the Preferences show.
"""
from __future__ import annotations

import sys
import time

import bpy

from .. import preferences
from ..launch import keep_renderer_warm, python_executable, user_environment
from .job import BackendJob, child_environment

POLL_SECONDS = 0.5
AUTO_START_DELAY = 5.0      # after enabling: let Blender finish starting first

_state = {"job": None, "status": "idle", "message": "", "started": 0.0, "seconds": None}


def command(python: str) -> list[str]:
    return [python, "-m", "backend", "warmup", "--progress", "json"]


def state() -> dict:
    """{"status": idle|running|compiling|compiled|warm|failed, "message", "seconds", "elapsed"}."""
    out = {k: _state[k] for k in ("status", "message", "seconds")}
    out["elapsed"] = time.monotonic() - _state["started"] if _state["job"] is not None else None
    return out


def running() -> bool:
    return _state["job"] is not None


def start() -> bool:
    """Start the background compile (False if one is running already)."""
    if _state["job"] is not None:
        return False
    try:
        job = BackendJob(command(python_executable()), env=child_environment(user_environment()))
    except OSError as exc:
        _state.update(status="failed", message=f"cannot start the renderer: {exc}")
        print(f"Lamina: {_state['message']}", file=sys.stderr)
        return False
    _state.update(job=job, status="running", message="starting the renderer ...",
                  started=time.monotonic(), seconds=None)
    if not bpy.app.timers.is_registered(_tick):
        bpy.app.timers.register(_tick, first_interval=POLL_SECONDS)
    return True


def pump() -> bool:
    """Read the child's events; True while it runs."""
    job = _state["job"]
    if job is None:
        return False
    for event in job.poll(0.0):
        kind = event.get("event")
        if kind == "compiling":
            _state.update(status="compiling", message="compiling render kernels (first run only) ...")
            print("Lamina: compiling render kernels in the background (first run only, about a minute) ...",
                  flush=True)
        elif kind == "compiled":
            seconds = float(event.get("seconds", 0.0))
            _state.update(status="compiled", seconds=seconds, message=f"compiled in {seconds:.0f} s")
            print(f"Lamina: compiled render kernels in {seconds:.1f} s", flush=True)
        elif kind == "warm":
            _state.update(status="warm", message="the render kernels are compiled")
    if not job.finished():
        return True
    code = job.wait()
    _state["job"] = None
    if code != 0 and _state["status"] not in ("compiled", "warm"):
        _state.update(status="failed", message=job.failure_message())
        print(f"Lamina: compiling the render kernels failed: {_state['message']}", file=sys.stderr)
    elif _state.pop("prestart", False):
        _prestart_preview_server()
    return False


def _prestart_preview_server() -> None:
    """After the automatic compile: load the material-preview renderer (render_server.py), so
    the first thumbnail does not wait for a process to start (Keep Renderer Warm)."""
    from .render_server import POOL
    if not keep_renderer_warm():
        return
    try:
        POOL.prestart("preview", python_executable(), child_environment(user_environment()))
    except OSError as exc:
        print(f"Lamina: cannot start the preview renderer: {exc}", file=sys.stderr)


def cancel() -> None:
    job = _state["job"]
    if job is not None:
        job.cancel()
        _state.update(job=None, status="idle", message="")


def _tick():
    alive = pump()
    _redraw_preferences()
    return POLL_SECONDS if alive else None


def _redraw_preferences() -> None:
    try:
        for window in bpy.context.window_manager.windows:
            for area in window.screen.areas:
                if area.type == "PREFERENCES":
                    area.tag_redraw()
    except (AttributeError, ReferenceError):
        pass


def _auto_start():
    if start():
        _state["prestart"] = True
    return None


class LAMINA_OT_compile_kernels(bpy.types.Operator):
    bl_idname = "lamina.compile_kernels"
    bl_label = "Compile Render Kernels"
    bl_description = ("Compile Lamina's render kernels now, in the background, so the first render "
                      "does not wait for it (about a minute, once per install or update)")

    def execute(self, context):
        if not start():
            self.report({"INFO"}, "Lamina: the render kernels are already being compiled")
        return {"FINISHED"}


def draw(layout) -> None:
    """The Preferences' row: the button and what the last compile did."""
    row = layout.row()
    s = state()
    row.enabled = s["status"] not in ("running", "compiling")
    row.operator(LAMINA_OT_compile_kernels.bl_idname, icon="FILE_REFRESH")
    text = {"running": s["message"], "compiling": f"Compiling ({(s['elapsed'] or 0):.0f} s) ...",
            "compiled": f"Compiled in {s['seconds'] or 0:.0f} s", "warm": "Compiled",
            "failed": f"Failed: {s['message']}"}.get(s["status"], "")
    if text:
        layout.label(text=text, icon="ERROR" if s["status"] == "failed" else "NONE")


def register():
    bpy.utils.register_class(LAMINA_OT_compile_kernels)
    preferences.EXTRA_DRAW.append(draw)
    # Enabled in the UI: compile in the background a little later (a warm cache: about a second).
    # Not under `blender -b` or the bpy module (scripts, farms, tests): there the render itself
    # compiles and says so, and a second compiling process would only compete with it.
    if not bpy.app.background:
        bpy.app.timers.register(_auto_start, first_interval=AUTO_START_DELAY)


def unregister():
    if bpy.app.timers.is_registered(_auto_start):
        bpy.app.timers.unregister(_auto_start)
    if bpy.app.timers.is_registered(_tick):
        bpy.app.timers.unregister(_tick)
    cancel()
    if draw in preferences.EXTRA_DRAW:
        preferences.EXTRA_DRAW.remove(draw)
    bpy.utils.unregister_class(LAMINA_OT_compile_kernels)
