"""Thumbnails for user presets, rendered by the backend in the background after a save.

Shipped presets come with thumbnails; a preset the user saves gets one the same way (the backend's
``presets thumbnails`` command: the same stage, camera, size and samples, so user and shipped icons
compare like for like). Rendering takes seconds to tens of seconds, so it runs in a child process,
one preset at a time. Saving the preset again, deleting it, turning the preference off or unloading
the add-on cancels its pending or running render. A failed render leaves the generic icon and prints
the backend's message to the console.

Everything here runs on Blender's main thread: there is no Python thread. A daemon thread that
waited on the child crashed Blender (SIGSEGV inside plain Python code in that thread while the main
thread was inside ``bpy.ops``; about 1 run in 6 of the preset tests) — Blender does not support
Python threads running alongside operators. Instead a ``bpy.app.timers`` tick polls the child
(``pump``), and ``request``/``cancel``/``wait`` pump too. Without an event loop (``blender -b``, the
``bpy`` module) timers never fire, so a queued second render starts at the next ``request``,
``cancel`` or ``wait``; the running one carries on in its own process regardless.
"""
from __future__ import annotations

import atexit
import subprocess
import sys
import tempfile
import time
from pathlib import Path

WORKERS = 1            # leave the other cores to Blender
POLL_SECONDS = 0.25    # timer interval while a render is pending or running

_queue: list[Path] = []          # preset files waiting, oldest first
_running: dict = {"path": None, "proc": None, "stderr": None, "cancelled": False}
_finished: list[dict] = []       # {"path", "code", "message", "cancelled"} of ended renders (tests)
_launch: dict = {"python": None, "env": None, "on_finished": None}
_ticking = [False]


def command(python: str, preset: Path) -> list[str]:
    return [python, "-m", "backend", "presets", "thumbnails", str(preset), "--no-gallery",
            "--workers", str(WORKERS)]


def request(preset: Path, python: str, env: dict, on_finished=None) -> None:
    """Queue a thumbnail render of ``preset`` (replacing a pending or running one for it).
    ``on_finished()`` runs on the main thread after each render ends (the preset list's cache of
    which thumbnails exist: presets/library.clear_cache)."""
    preset = Path(preset)
    cancel(preset)
    _launch.update(python=python, env=env, on_finished=on_finished)
    _queue.append(preset)
    pump()
    _ensure_ticking()


def cancel(preset: Path | None = None, timeout: float = 10.0) -> None:
    """Drop the pending render of ``preset`` and stop it if it is running (None: every render).
    Returns once the process has exited, so the caller may delete or rewrite the preset's files
    (a stopped render still writes what it has, like any interrupted render)."""
    if preset is None:
        _queue.clear()
    else:
        _queue[:] = [p for p in _queue if p != Path(preset)]
    proc = _running["proc"]
    if proc is not None and (preset is None or _running["path"] == Path(preset)):
        _running["cancelled"] = True
        proc.terminate()
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    pump()


def busy() -> bool:
    return bool(_queue) or _running["proc"] is not None


def wait(timeout: float) -> bool:
    """Block until no render is pending or running (tests, scripts); False on timeout."""
    deadline = time.monotonic() + timeout
    while True:
        pump()
        if not busy():
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)


def finished() -> list[dict]:
    return list(_finished)


def pump() -> None:
    """Collect a render that ended, then start the next queued one."""
    proc = _running["proc"]
    if proc is not None and proc.poll() is not None:
        _collect(proc)
        _forget_entries()
    while _running["proc"] is None and _queue:
        _start(_queue.pop(0))


def _start(preset: Path) -> None:
    # stderr goes to a file, not a pipe: nothing reads a pipe while the render runs, and a full
    # pipe would stall the child.
    err = tempfile.TemporaryFile(mode="w+", encoding="utf-8", errors="replace")
    try:
        proc = subprocess.Popen(command(_launch["python"], preset), env=_launch["env"],
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err)
    except OSError as exc:
        err.close()
        _finished.append({"path": str(preset), "code": None, "message": str(exc), "cancelled": False})
        print(f"Lamina: cannot render the thumbnail of {preset.name}: {exc}", file=sys.stderr)
        return
    _running.update(path=preset, proc=proc, stderr=err, cancelled=False)


def _collect(proc: subprocess.Popen) -> None:
    preset, err, cancelled = _running["path"], _running["stderr"], _running["cancelled"]
    _running.update(path=None, proc=None, stderr=None, cancelled=False)
    err.seek(0)
    lines = [l for l in err.read().splitlines() if l.strip()]
    err.close()
    message = lines[-1] if lines else ""
    _finished.append({"path": str(preset), "code": proc.returncode, "message": message,
                      "cancelled": cancelled})
    if proc.returncode != 0 and not cancelled:
        print(f"Lamina: thumbnail of {preset.name} failed: {message}", file=sys.stderr)


def _tick():
    """Timer callback: returns the next interval, or None to stop while idle."""
    done = len(_finished)
    pump()
    if len(_finished) > done:
        _redraw_preset_views()
    if busy():
        return POLL_SECONDS
    _ticking[0] = False
    return None


def _redraw_preset_views() -> None:
    """Redraw the Properties editors (the Preset Library panel shows thumbnails as they arrive;
    menus read the list again when they open). Timers run on the main thread, where this is safe."""
    try:
        import bpy
        windows = bpy.context.window_manager.windows
    except (ImportError, AttributeError):
        return
    for window in windows:
        screen = window.screen
        for area in (screen.areas if screen is not None else ()):
            if area.type == "PROPERTIES":
                area.tag_redraw()


def _ensure_ticking() -> None:
    if _ticking[0] or not busy():
        return
    try:
        import bpy
    except ImportError:          # outside Blender (unit tests): callers pump through wait()
        return
    # persistent: opening another .blend must not drop the tick of a render still running
    bpy.app.timers.register(_tick, first_interval=POLL_SECONDS, persistent=True)
    _ticking[0] = True


def stop_ticking() -> None:
    """Unregister the timer (add-on unload); call after ``cancel()``."""
    if not _ticking[0]:
        return
    try:
        import bpy
        if bpy.app.timers.is_registered(_tick):
            bpy.app.timers.unregister(_tick)
    except ImportError:
        pass
    _ticking[0] = False


def _forget_entries() -> None:
    """The preset list caches which thumbnails exist: let the next menu draw look again."""
    if _launch["on_finished"] is not None:
        _launch["on_finished"]()


# Blender may exit without unregistering add-ons: do not leave a renderer running behind it.
atexit.register(cancel)
