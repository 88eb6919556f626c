"""Thumbnails for user presets, rendered by the backend in the background after a save.

Shipped presets come with thumbnails; a preset the user saves gets one the same way (the backend's
``presets thumbnails`` command: the same stage, camera, size and samples, so user and shipped icons
compare like for like). Rendering takes tens of seconds, so it runs in a child process, one preset at
a time, driven by a daemon thread (no bpy in the thread: it only starts processes and clears the
preset list's cache so menus pick the new icon up). Saving the preset again, deleting it,
turning the preference off or unloading the add-on cancels its pending or running render. A
failed render leaves the generic icon and prints the backend's message to the console.
"""
from __future__ import annotations

import atexit
import subprocess
import sys
import threading
from pathlib import Path

WORKERS = 1            # leave the other cores to Blender
POLL_SECONDS = 0.2     # how often the worker thread checks a running render for cancellation

_lock = threading.Lock()
_queue: list[Path] = []          # preset files waiting, oldest first
_running: dict = {"path": None, "proc": None, "cancelled": False}
_finished: list[dict] = []       # {"path", "code", "message", "cancelled"} of ended renders (tests)
_thread: threading.Thread | None = None
_idle = threading.Condition(_lock)


def command(python: str, preset: Path) -> list[str]:
    return [python, "-m", "backend", "presets", "thumbnails", str(preset), "--no-gallery",
            "--workers", str(WORKERS)]


def request(preset: Path, python: str, env: dict) -> None:
    """Queue a thumbnail render of ``preset`` (replacing a pending or running one for it)."""
    preset = Path(preset)
    cancel(preset)
    with _lock:
        _queue.append(preset)
        global _thread
        if _thread is None or not _thread.is_alive():
            _thread = threading.Thread(target=_work, args=(python, env), name="lamina-thumbnails", daemon=True)
            _thread.start()


def cancel(preset: Path | None = None, timeout: float = 10.0) -> None:
    """Drop the pending render of ``preset`` and stop it if it is running (None: every render).
    Returns once the process has exited, so the caller may delete or rewrite the preset's files
    (a stopped render still writes what it has, like any interrupted render)."""
    victim = None
    with _lock:
        if preset is None:
            _queue.clear()
        else:
            _queue[:] = [p for p in _queue if p != Path(preset)]
        proc = _running["proc"]
        if proc is not None and (preset is None or _running["path"] == Path(preset)):
            _running["cancelled"] = True
            proc.terminate()
            victim = proc
    if victim is not None:
        try:
            victim.wait(timeout)
        except subprocess.TimeoutExpired:
            victim.kill()
            victim.wait()


def wait(timeout: float) -> bool:
    """Block until no render is pending or running (tests); False on timeout."""
    with _idle:
        return _idle.wait_for(lambda: not _queue and _running["proc"] is None, timeout)


def finished() -> list[dict]:
    with _lock:
        return list(_finished)


def _work(python: str, env: dict) -> None:
    while True:
        with _lock:
            if not _queue:
                _idle.notify_all()
                return
            preset = _queue.pop(0)
            try:
                proc = subprocess.Popen(command(python, preset), env=env, stdin=subprocess.DEVNULL,
                                        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            except OSError as exc:
                _finished.append({"path": str(preset), "code": None, "message": str(exc), "cancelled": False})
                print(f"Lamina: cannot render the thumbnail of {preset.name}: {exc}", file=sys.stderr)
                continue
            _running.update(path=preset, proc=proc, cancelled=False)
        _, err = proc.communicate()
        lines = [l for l in (err or "").splitlines() if l.strip()]
        message = lines[-1] if lines else ""
        with _lock:
            cancelled = _running["cancelled"]
            _running.update(path=None, proc=None, cancelled=False)
            _finished.append({"path": str(preset), "code": proc.returncode, "message": message,
                              "cancelled": cancelled})
            _idle.notify_all()
        if proc.returncode != 0 and not cancelled:
            print(f"Lamina: thumbnail of {preset.name} failed: {message}", file=sys.stderr)
        _forget_entries()


def _forget_entries() -> None:
    """The preset list caches which thumbnails exist: let the next menu draw look again."""
    from . import library
    library.clear_cache()


# Blender may exit without unregistering add-ons: do not leave a renderer running behind it.
atexit.register(cancel)
