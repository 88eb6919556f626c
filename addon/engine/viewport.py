"""Rendered shading in the 3D viewport: the LAMINA engine's ``view_update`` and ``view_draw``.

One renderer *session* per viewport (``python -m backend session``, docs/session.md) in a child
process: the scene is exported and sent once; afterwards every depsgraph update is exported again
through ``LiveExporter`` (which re-reads only what the update invalidated) and only the sections
that changed are sent, with a new generation; view moves and region resizes send only the camera
and film. The session restarts its progressive render at each edit.

Blender's rules: nothing here runs outside the main thread. The session's output is read from
files by a timer (``_tick``, every 30 ms while a session renders, 250 ms otherwise), which asks
for a redraw (``RenderEngine.tag_redraw``) when a frame is waiting; ``view_draw`` then uploads it
as a float texture and draws it (``draw.py``).

Edits and stale frames: the client only hands out frames of its newest generation, and
``view_draw`` only draws a texture of that generation — after an edit has been sent, an older image
is never drawn again (the region shows nothing until the new one arrives). Edits made while the
session has not shown the previous one yet are coalesced here and sent together once it has
(after the new image stayed at least ``HOLD`` seconds on screen, or after ``MAX_WAIT``).

Stopping: leaving Rendered mode frees the engine (``free``, from the engine's ``__del__``; the
timer also notices a dead engine); opening another file (``load_pre``), disabling the add-on and
quitting (``atexit``) stop every session. A session whose stdin closes ends by itself too, so
even a crashed Blender leaves no renderer behind.

A *standby* session is started ahead of time (preference *Pre-start Viewport Renderer*) while a
scene uses Lamina and no viewport renders: its interpreter, libraries and compiled kernels are
loaded while the user is still modelling, so Rendered mode starts with the scene export.
"""
from __future__ import annotations

import atexit
import shutil
import sys
import tempfile
import time
import traceback
import weakref
from pathlib import Path

import bpy

from .. import preferences
from ..export.camera import CameraError, camera_json, film_json
from ..export.live import LiveExporter
from ..export.scene import ExportError, dumps, warning_text
from ..export.stack import StackError
from ..export.view import film_crop, film_size, ndc_rect, project, region_border, view_camera
from .job import child_environment
from ..launch import keep_files, python_executable, user_environment
from .session_client import SessionClient, session_command

BUSY_INTERVAL = 0.03       # seconds between looks at a rendering session's output
IDLE_INTERVAL = 0.25       # ... at an idle one
STANDBY_INTERVAL = 1.0     # ... when no viewport renders (standby upkeep)
MAX_WAIT = 1.0             # an edit waits at most this long for the previous edit's first frame
HOLD = 0.1                 # a new image stays on screen at least this long before the next edit
STOP_GRACE = 0.2           # seconds a session may take to end before its process group is killed


class _viewport_denoise_settings:
    """Cycles' viewport denoising quality and prefilter as its final-render ones for one call of
    the file denoiser (which reads the final-render ones), restored after."""

    NAMES = (("denoising_quality", "preview_denoising_quality"),
             ("denoising_prefilter", "preview_denoising_prefilter"))

    def __init__(self, scene):
        self.cycles = getattr(scene, "cycles", None)
        self.saved = []

    def __enter__(self):
        for final, preview in self.NAMES if self.cycles is not None else ():
            try:
                self.saved.append((final, getattr(self.cycles, final)))
                setattr(self.cycles, final, getattr(self.cycles, preview))
            except (AttributeError, TypeError):
                pass
        return self

    def __exit__(self, *exc):
        for name, value in self.saved:
            try:
                setattr(self.cycles, name, value)
            except (AttributeError, TypeError):
                pass
        return False


def make_drawer():
    """The object that uploads and draws frames (tests replace this function)."""
    from .draw import GPUDrawer
    return GPUDrawer()


def _settings():
    return python_executable(), user_environment(), keep_files()


def _command(python: str, frames: Path, workers: int) -> list[str]:
    return session_command(python, frames, samples=32, workers=workers, warm=True)


def _pixel_size(engine, scene) -> int:
    try:
        return max(1, int(engine.get_preview_pixel_size(scene)))
    except (AttributeError, TypeError, RuntimeError):
        return 1


def _console(message: str) -> None:
    print(f"Lamina viewport: {message}", file=sys.stderr)


def start_client(workers: int) -> SessionClient:
    python, env, _ = _settings()
    folder = Path(tempfile.mkdtemp(prefix="lamina-viewport-"))
    cmd = _command(python, folder / "frames", workers)
    try:
        return SessionClient(cmd, folder, env=child_environment(env))
    except OSError as exc:
        shutil.rmtree(folder, ignore_errors=True)
        raise ExportError(f"cannot start the viewport renderer ({python}): {exc.strerror or exc}") from None


class ViewportRender:
    """The viewport rendering of one engine instance (one 3D view in Rendered mode)."""

    def __init__(self, engine):
        self.engine_ref = weakref.ref(engine)
        self.client: SessionClient | None = None
        self.live: LiveExporter | None = None
        self.folder: Path | None = None
        self.pending: dict = {}
        self.view = None                 # (camera, film) as last computed
        self.samples = None
        self.drawer = None
        self.texture_generation = 0
        self.texture_info = None         # the drawn frame's header (spp, scale, ...)
        self.denoised = False            # the drawn image is the denoised final frame
        self.denoise_error: str | None = None
        self.denoise_request = None      # (frame, scene, view layer) for the timer to denoise
        self.denoised_frame = None       # the denoised image of the newest final frame
        self.shown_at = None             # when the current generation's first image was drawn
        self.shown_generation = 0
        self.error: str | None = None    # an export problem (shown; the session keeps going)
        self.reported: set[str] = set()
        self.started = time.perf_counter()
        self.first_frame_seconds = None
        self.freed = False
        _SESSIONS.append(self)
        _ensure_timer()

    # ------------------------------------------------------------------ Blender callbacks

    def update(self, engine, context, depsgraph) -> None:
        """view_update: the scene changed (or the viewport entered Rendered mode)."""
        try:
            scene = depsgraph.scene
            if not self.scene_sent:
                self._start(engine, context, depsgraph)
            else:
                self.live.invalidate(depsgraph)
                doc = self.live.export(depsgraph, *self.view)
                self._queue(self.live.changes(doc))
                self._note(self.live.notes)
            self.error = None
            self._samples(scene)
            self.flush()
        except (ExportError, CameraError, StackError) as exc:
            self._fail(str(exc))
        except Exception as exc:  # noqa: BLE001 - shown as one line, never a traceback in the UI
            self._fail(f"internal error: {type(exc).__name__}: {exc}", trace=True)
        engine.update_stats("", self.status_text())

    def draw(self, engine, context, depsgraph) -> None:
        """view_draw: draw the newest frame of the newest generation (or nothing)."""
        scene = depsgraph.scene
        try:
            if not self.scene_sent:
                if self.error is None:
                    self._start(engine, context, depsgraph)
            else:
                view = self.compute_view(engine, context, scene)
                if view != self.view:
                    self.view = view
                    self._queue(self.live.view_changes(*view))
                self.flush()
                self.client.poll()
                frame = self.client.take_frame()
                if frame is not None:
                    if self.drawer is None:
                        self.drawer = make_drawer()
                    self.drawer.upload(frame)
                    self.texture_generation = frame.generation
                    self.texture_info = frame
                    self.denoised = False
                self._denoised_view(scene, depsgraph)
                if self.drawer is not None and self.texture_generation == self.client.generation:
                    region = context.region
                    self.drawer.draw(engine, scene, region.width, region.height)
                    if self.shown_generation != self.texture_generation:
                        self.shown_generation = self.texture_generation
                        self.shown_at = time.perf_counter()
                        if self.first_frame_seconds is None:
                            self.first_frame_seconds = self.shown_at - self.started
        except (ExportError, CameraError) as exc:
            self._fail(str(exc))
        except Exception as exc:  # noqa: BLE001
            self._fail(f"internal error: {type(exc).__name__}: {exc}", trace=True)
        engine.update_stats("", self.status_text())

    def _denoised_view(self, scene, depsgraph) -> None:
        """Render › Denoise Viewport, the drawing side: the final frame (Viewport Samples reached)
        is drawn as rendered first and asked of the timer to denoise (``denoise_pending``); once
        that is done its denoised image is drawn. Switched off, the frame as rendered again."""
        info = self.texture_info
        if info is None:
            return
        want = info.final and info.features is not None and bool(scene.lamina.use_viewport_denoising)
        done = self.denoised_frame is not None and self.denoised_frame.frame == info.frame
        if want and not self.denoised:
            if done:
                self.drawer.upload(self.denoised_frame)
                self.denoised = True
            elif self.denoise_request is None or self.denoise_request[0].frame != info.frame:
                self.denoise_request = (info, scene, depsgraph.view_layer)
        elif not want and self.denoised:
            self.drawer.upload(info)
            self.denoised = False

    def denoise_pending(self) -> bool:
        """Timer: denoise the frame ``_denoised_view`` asked for (True: redraw). In the timer, not
        in view_draw: the denoiser reads its quality from the scene, which is set here for the
        call (Cycles' own viewport denoising settings, Render › Denoise › Viewport), and a write to
        a scene is not allowed while drawing. It runs in Blender's main thread (Blender does not
        support Python threads): 1.4 s for a 960×540 view on the 2-core development machine with
        Cycles' viewport defaults (Balanced, Fast prefilter; 5.6 s with the final render's High,
        Accurate), once per finished view."""
        request, self.denoise_request = self.denoise_request, None
        if request is None:
            return False
        frame, scene, view_layer = request
        if self.texture_info is None or self.texture_info.frame != frame.frame:
            return False                                    # an edit came in the meantime
        from dataclasses import replace
        from .denoise import DenoiseError, denoise_image
        try:
            with _viewport_denoise_settings(scene):
                pixels = denoise_image(frame.pixels, frame.features, frame.spp, self.folder / "denoise",
                                       scene, view_layer, bpy.context.preferences)
        except (DenoiseError, OSError, ReferenceError) as exc:
            if self.denoise_error != str(exc):
                _console(f"Denoise: {exc} (the viewport shows the image as rendered)")
            self.denoise_error = str(exc)
            return True
        self.denoise_error = None
        self.denoised_frame = replace(frame, pixels=pixels)
        return True

    # ------------------------------------------------------------------ session

    @property
    def scene_sent(self) -> bool:
        """The session has a whole scene (edits are sent as updates only after that)."""
        return self.client is not None and self.live is not None and self.live.sent is not None

    def _start(self, engine, context, depsgraph) -> None:
        """Start (or take) the session if there is none, and send it the whole scene. An export
        that fails leaves the session waiting for the scene: the next update tries again."""
        scene = depsgraph.scene
        self.view = self.compute_view(engine, context, scene)
        client = self.client
        if client is None:
            workers = int(scene.lamina.workers)
            python, env, _ = _settings()
            client = take_standby(_command(python, Path("frames"), workers))
            if client is None:
                client = start_client(workers)
            self.client, self.folder = client, client.folder
            self.live = LiveExporter(self.folder / "scene")
        self.pending = {}
        doc = self.live.export(depsgraph, *self.view)
        self.live.sent = doc
        self._note(self.live.notes)
        path = self.folder / "scene" / "scene.json"
        tmp = path.with_suffix(".tmp")
        tmp.write_text(dumps(doc), encoding="utf-8")
        tmp.replace(path)
        self._samples(scene)
        client.send_scene(path)

    def _samples(self, scene) -> None:
        samples = int(scene.lamina.viewport_samples)
        if self.client is not None and samples != self.samples:
            self.samples = samples
            self.client.set_samples(samples)

    def _queue(self, changes: dict) -> None:
        for key, value in changes.items():
            if key in ("materials", "meshes") and key in self.pending:
                self.pending[key].update(value)
            else:
                self.pending[key] = value

    def flush(self) -> bool:
        """Send the coalesced edits if the session has shown the previous one (or took too long).
        Returns whether an edit was sent."""
        c = self.client
        if not self.pending or c is None or c.error is not None:
            return False
        now = time.perf_counter()
        answered = c.answered >= c.generation
        shown = c.scene_error is not None or (
            self.shown_generation == c.generation and self.shown_at is not None
            and now - self.shown_at >= HOLD)
        if not ((answered and shown) or now - c.sent_at >= MAX_WAIT):
            return False
        changes, self.pending = self.pending, {}
        c.send_update(changes)
        return True

    def tick(self) -> bool:
        """Timer: read the session's output, send waiting edits. True if the region should redraw."""
        c = self.client
        if c is None:
            return False
        if self.denoise_pending():
            return True
        before = (c.error, c.scene_error, c.idle, c.ready, c.compiling, c.spp)
        c.poll()
        sent = self.flush()
        after = (c.error, c.scene_error, c.idle, c.ready, c.compiling, c.spp)
        if c.error is not None and c.error not in self.reported:
            self.reported.add(c.error)
            _console(c.error)
        if c.scene_error is not None and c.scene_error not in self.reported:
            self.reported.add(c.scene_error)
            _console(c.scene_error)
        for warning in c.warnings:                  # the renderer's own warnings, once each
            if warning not in self.reported:
                self.reported.add(warning)
                _console(f"warning: {warning}")
        return c.frame_waiting or sent or before != after or bool(self.pending)

    @property
    def busy(self) -> bool:
        c = self.client
        return c is not None and c.error is None and (not c.idle or bool(self.pending))

    # ------------------------------------------------------------------ view

    def compute_view(self, engine, context, scene) -> tuple[dict, dict]:
        """The camera and film of the region: perspective, orthographic or the camera view
        (depth of field, render border inside the camera frame); a View Region border elsewhere."""
        region, rv3d, space = context.region, context.region_data, context.space_data
        width, height = int(region.width), int(region.height)
        pixel_size = _pixel_size(engine, scene)
        camera = view_camera(rv3d.view_matrix, rv3d.window_matrix, bool(rv3d.is_perspective))
        border = frame = None
        render = scene.render
        if rv3d.view_perspective == "CAMERA" and scene.camera is not None:
            cam = scene.camera
            try:
                dof = camera_json(cam, scene).get("dof") if cam.type == "CAMERA" else None
            except CameraError:
                dof = None
            if dof is not None:
                camera["dof"] = dof
            if render.use_border and cam.type == "CAMERA":
                frame = ndc_rect(project(rv3d.window_matrix, cam.data.view_frame(scene=scene)))
                border = (render.border_min_x, render.border_min_y, render.border_max_x, render.border_max_y)
        elif space is not None and getattr(space, "use_render_border", False):
            border = (space.render_border_min_x, space.render_border_min_y,
                      space.render_border_max_x, space.render_border_max_y)
        fw, fh = film_size(width, height, pixel_size)
        film = {"width": fw, "height": fh, "filter": film_json(scene, fw, fh)["filter"]}
        if render.film_transparent:
            film["transparent"] = True
        crop = film_crop(region_border(frame, border, width, height), width, height, pixel_size)
        if crop is not None:
            film["crop"] = crop
        return camera, film

    # ------------------------------------------------------------------ messages

    def status_text(self) -> str:
        c = self.client
        if self.error is not None:
            return f"Lamina | Error: {self.error}"
        if c is None:
            return "Lamina | Starting"
        if c.error is not None:
            return f"Lamina | Viewport renderer failed: {c.error}"
        if c.scene_error is not None:
            return f"Lamina | Error: {c.scene_error}"
        if c.compiling:
            return "Lamina | Compiling render kernels (first run only)"
        info = self.texture_info
        if info is None or self.texture_generation != c.generation:
            return "Lamina | Loading scene" if c.generation <= 1 else "Lamina | Updating"
        target = f"/{self.samples}" if self.samples else ""
        if info.scale > 1:
            return f"Lamina | Preview 1/{info.scale} resolution"
        text = f"Lamina | Sample {info.spp}{target}"
        if not (c.idle and info.final):
            return text
        if self.denoised:
            return text + " | Done, denoised"
        if self.denoise_error is not None:
            return text + f" | Done | Denoise failed: {self.denoise_error}"
        return text + " | Done"

    def _note(self, notes) -> None:
        text = warning_text(notes)
        if text and text not in self.reported:
            self.reported.add(text)
            _console(text)

    def _fail(self, message: str, trace: bool = False) -> None:
        self.error = message
        if message not in self.reported:
            self.reported.add(message)
            _console(message)
            if trace and bpy.app.debug_python:
                traceback.print_exc()

    # ------------------------------------------------------------------ end

    def free(self, grace: float = STOP_GRACE) -> None:
        """Stop the session (and its whole process group) and remove its files. Idempotent."""
        if self in _SESSIONS:
            _SESSIONS.remove(self)
        if self.freed:
            return
        self.freed = True
        if self.drawer is not None:
            try:
                self.drawer.free()
            except Exception:  # noqa: BLE001 - no GPU context any more
                pass
            self.drawer = None
        client, self.client = self.client, None
        if client is not None:
            client.stop(grace)
            _remove(client.folder)


def _remove(folder: Path | None) -> None:
    if folder is None:
        return
    try:
        keep = _settings()[2]
    except Exception:  # noqa: BLE001 - add-on unregistered
        keep = False
    if keep:
        print(f"Lamina: viewport session files kept in {folder}")
    else:
        shutil.rmtree(folder, ignore_errors=True)


# ---------------------------------------------------------------------- engine entry points

def view_update(engine, context, depsgraph) -> None:
    vr = getattr(engine, "viewport", None)
    if vr is None or vr.freed:
        vr = engine.viewport = ViewportRender(engine)
    vr.update(engine, context, depsgraph)


def view_draw(engine, context, depsgraph) -> None:
    vr = getattr(engine, "viewport", None)
    if vr is None or vr.freed:
        vr = engine.viewport = ViewportRender(engine)
    vr.draw(engine, context, depsgraph)


def free_engine(engine) -> None:
    vr = getattr(engine, "viewport", None)
    if vr is not None:
        vr.free()


# ---------------------------------------------------------------------- all sessions

_SESSIONS: list[ViewportRender] = []
_STANDBY: dict = {"client": None}


def _engine_alive(engine) -> bool:
    try:
        engine.is_preview                      # raises once Blender has freed the engine
    except ReferenceError:
        return False
    return True


def _tick():
    interval = STANDBY_INTERVAL
    for vr in list(_SESSIONS):
        engine = vr.engine_ref()
        if engine is None or not _engine_alive(engine):
            vr.free()
            continue
        try:
            redraw = vr.tick()
        except Exception as exc:  # noqa: BLE001
            vr._fail(f"internal error: {type(exc).__name__}: {exc}", trace=True)
            redraw = True
        if redraw:
            engine.tag_redraw()
        interval = min(interval, BUSY_INTERVAL if vr.busy else IDLE_INTERVAL)
    try:
        _manage_standby()
    except Exception as exc:  # noqa: BLE001 - never let the timer die
        _console(f"standby renderer: {type(exc).__name__}: {exc}")
    return interval


def _ensure_timer() -> None:
    if not bpy.app.timers.is_registered(_tick):
        bpy.app.timers.register(_tick, first_interval=BUSY_INTERVAL, persistent=True)


def _standby_wanted() -> bool:
    if bpy.app.background or _SESSIONS:
        return False
    prefs = preferences.get()
    if prefs is None or not prefs.viewport_prestart:
        return False
    try:
        return any(w.scene is not None and w.scene.render.engine == "LAMINA"
                   for w in bpy.context.window_manager.windows)
    except (AttributeError, ReferenceError):
        return False


def _manage_standby() -> None:
    client = _STANDBY["client"]
    if client is not None:
        client.poll()
        if client.error is not None or not client.alive:
            _drop_standby()
            client = None
    wanted = _standby_wanted()
    if wanted and client is None and time.monotonic() >= _STANDBY.get("retry_at", 0.0):
        scene = bpy.context.window_manager.windows[0].scene
        workers = int(scene.lamina.workers) if scene is not None else 0
        try:
            _STANDBY["client"] = start_client(workers)
        except ExportError as exc:
            _STANDBY["retry_at"] = time.monotonic() + 60.0      # say it once a minute at most
            _console(str(exc))
    elif not wanted and client is not None and not _SESSIONS:
        _drop_standby()


def _drop_standby() -> None:
    client, _STANDBY["client"] = _STANDBY["client"], None
    if client is not None:
        client.kill()
        _remove(client.folder)


def _without_frames(cmd: list[str]) -> list[str]:
    out = list(cmd)
    if "--frames" in out:
        i = out.index("--frames")
        del out[i:i + 2]
    return out


def take_standby(cmd: list[str]) -> SessionClient | None:
    """The pre-started session if it runs the same command (frames folder aside), else None."""
    client, _STANDBY["client"] = _STANDBY["client"], None
    if client is None:
        return None
    client.poll()
    same = _without_frames(client.cmd) == _without_frames(cmd)
    if same and client.alive and client.error is None:
        return client
    client.kill()
    _remove(client.folder)
    return None


def stop_all(grace: float = STOP_GRACE) -> None:
    """Stop every viewport session and the standby (file closed, add-on disabled)."""
    for vr in list(_SESSIONS):
        vr.free(grace)
    _drop_standby()


def kill_all() -> None:
    """Interpreter exit: end every session's process group at once and remove its folder."""
    for vr in list(_SESSIONS):
        if vr.client is not None:
            vr.client.kill()
            _remove(vr.folder)
    client = _STANDBY["client"]
    if client is not None:
        client.kill()
        _remove(client.folder)


@bpy.app.handlers.persistent
def _load_pre(*_args):
    stop_all()


def register():
    bpy.app.handlers.load_pre.append(_load_pre)
    atexit.register(kill_all)
    if not bpy.app.background:
        _ensure_timer()


def unregister():
    if _load_pre in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_load_pre)
    if bpy.app.timers.is_registered(_tick):
        bpy.app.timers.unregister(_tick)
    stop_all()
    atexit.unregister(kill_all)
