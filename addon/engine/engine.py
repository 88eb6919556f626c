"""The ``LAMINA`` render engine: export → backend child process → Render Result.

Works for F12, animations, ``blender -b file.blend -E LAMINA -f 1`` / ``-a`` and material
previews. Everything that goes wrong ends in ``report({'ERROR'})`` + ``error_set`` (so
``bpy.ops.render.render`` raises in background mode) — never in a silent black image.
"""
from __future__ import annotations

import atexit
import shutil
import sys
import tempfile
import time
import traceback
from pathlib import Path

import bpy

from .. import preferences
from ..export import export_scene
from ..export.camera import CameraError, border_rect, eye_camera_json, film_size, view_camera_object
from ..export.passes import requested as requested_passes
from ..export.scene import ExportError
from .job import BackendJob, child_environment, render_command
from ..launch import keep_files, keep_renderer_warm, python_executable, user_environment
from .denoise import NOISY_PASS, DenoiseError, denoise_image
from .pixels import ALBEDO_PASS, NORMAL_PASS, fill_passes, load_npy, pass_npy_path
from . import viewport
from .render_server import POOL

# The warning of an animation's last frame, per scene (``LaminaRenderEngine._warn_once``).
_ANIMATION_WARNINGS: dict = {}

PREVIEW_WORKERS = 1          # worker processes cost ~1 s to start; thumbnails are small


class RenderFailure(Exception):
    """A failure with a message meant for the user."""


def _preview_samples() -> int:
    prefs = preferences.get()
    return int(prefs.preview_samples) if prefs is not None else 16


def _format_seconds(seconds: float) -> str:
    seconds = max(0.0, float(seconds))
    if seconds < 60:
        return f"{seconds:.1f} s"
    m, s = divmod(int(round(seconds)), 60)
    if m < 60:
        return f"{m}:{s:02d}"
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}"


#: Blender prints a report on the console cut at about 1000 characters ("... truncated").
REPORT_PRINT_LIMIT = 900


def _console(text: str) -> str:
    """Print a warning or error the engine is about to report, where Blender will not print it
    whole, and return the text to report. Under `blender -b` (and the bpy module) Blender prints
    every report itself ("Warning: ...", "Error: ..."): printing it here too showed each message
    twice. A report longer than Blender prints whole is printed here in full (a farm's log keeps
    it) and reported as a pointer to that line, so the console holds it once and complete."""
    if not bpy.app.background:
        print(text, file=sys.stderr)
        return text
    if len(text) <= REPORT_PRINT_LIMIT:
        return text
    print(text, file=sys.stderr, flush=True)
    head = text.split(":", 1)[0] if ":" in text[:80] else "Lamina"
    return f"{head} (the full message, {len(text)} characters, is on the console line above)"


class LaminaRenderEngine(bpy.types.RenderEngine):
    bl_idname = "LAMINA"
    bl_label = "Lamina"
    bl_use_preview = True
    bl_use_postprocess = True
    bl_use_eevee_viewport = True          # viewport Material Preview is drawn by EEVEE
    bl_use_shading_nodes_custom = False   # materials use the standard shader nodes

    # Blender ≥ 4.4 passes arguments to __init__; the old no-argument form silently skips renders.
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.job = None
        self.viewport = None             # Rendered shading (viewport.py)

    def __del__(self):
        job = getattr(self, "job", None)
        if job is not None:
            try:
                job.kill_group()
            except Exception:  # noqa: BLE001 - interpreter shutdown
                pass
        try:
            viewport.free_engine(self)   # leaving Rendered mode: the session ends with the engine
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass

    # ------------------------------------------------------------------ viewport

    def view_update(self, context, depsgraph):
        viewport.view_update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        viewport.view_draw(self, context, depsgraph)

    def cancel_requested(self) -> bool:
        """Esc in the UI (``test_break``). A plain method so tests can simulate it: RNA functions
        such as ``test_break`` cannot be overridden on the class once it is registered."""
        return bool(self.test_break())

    # ------------------------------------------------------------------ passes

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        self.register_pass(scene, renderlayer, ALBEDO_PASS, 3, "RGB", "COLOR")
        self.register_pass(scene, renderlayer, NORMAL_PASS, 3, "XYZ", "VECTOR")
        if scene.lamina.use_denoising:
            self.register_pass(scene, renderlayer, NOISY_PASS, 4, "RGBA", "COLOR")
        for _, label, chans, kind in requested_passes(renderlayer):
            self.register_pass(scene, renderlayer, label, len(chans), chans, kind)

    # ------------------------------------------------------------------ render

    def render(self, depsgraph):
        workdir = Path(tempfile.mkdtemp(prefix="lamina-"))
        keep = False
        self._exported = None
        self._renderer_warnings: list[str] = []
        scene = depsgraph.scene
        self._frame_of = (scene.name, bool(self.is_animation) and scene.frame_current > scene.frame_start)
        try:
            keep = keep_files() and not self.is_preview
            self._render(depsgraph, workdir)
            self._warn_once()
        except (RenderFailure, ExportError) as exc:
            self._warn_once()
            self._fail(str(exc))
        except Exception as exc:  # noqa: BLE001 - anything else still must not pass silently
            traceback.print_exc()
            self._warn_once()
            self._fail(f"internal error: {type(exc).__name__}: {exc}")
        finally:
            if self.job is not None:
                self.job.kill_group()          # no orphan, whatever happened above
                self.job = None
            if keep:
                print(f"Lamina: render files kept in {workdir}")
            else:
                shutil.rmtree(workdir, ignore_errors=True)

    def _warn_once(self) -> None:
        """The render's one warning: everything the export and the renderer could not render as
        asked, by Blender name (object, material, node...). In an animation a frame whose warning
        is the previous frame's says nothing: a long animation would print the same lines once
        per frame, and Blender keeps every report of the job."""
        exported = getattr(self, "_exported", None)
        if exported is None or self.is_preview:
            return
        text = exported.warning_text(extra=self._renderer_warnings)
        self._exported = None                    # once per render
        key, later_frame = getattr(self, "_frame_of", (None, False))
        previous = _ANIMATION_WARNINGS.get(key) if later_frame else None
        _ANIMATION_WARNINGS[key] = text
        if text and text != previous:
            self.report({"WARNING"}, _console(text))

    def _fail(self, message: str) -> None:
        message = f"Lamina: {message}"
        if self.is_preview:
            print(message, file=sys.stderr)
            return                               # thumbnails fail quietly (console only)
        message = _console(message)
        # report() alone: it makes bpy.ops.render.render raise with the message (background
        # mode) and shows it in the status bar; error_set() as well would show it twice (and on
        # its own crashed bpy 5.0.1 in background mode).
        self.report({"ERROR"}, message)

    def _render(self, depsgraph, workdir: Path) -> None:
        scene = depsgraph.scene
        settings = scene.lamina
        width, height = film_size(scene.render)
        rect = border_rect(scene.render, width, height) or (0, 0, width, height)
        preview = self.is_preview

        self.update_stats("", "Lamina | Exporting scene")
        t0 = time.perf_counter()
        seed_offset = scene.frame_current if settings.use_animated_seed else 0
        camera_object = self.camera_override or scene.camera
        view_names, views = self._views(depsgraph, camera_object, rect) if not preview else ([None], None)
        exported = export_scene(depsgraph, workdir / "scene",
                                camera_object=camera_object,
                                samples=_preview_samples() if preview else None,
                                seed_offset=seed_offset, preview=preview, views=views,
                                frame_set=lambda f, sub: self.frame_set(f, subframe=sub))
        self._exported = exported                # its notes are reported with the renderer's, once
        if not preview:
            print(f"Lamina: exported {exported.stats['triangles']} triangles "
                  f"({exported.stats['meshes']} meshes, {exported.stats['instances']} instances) "
                  f"in {time.perf_counter() - t0:.2f} s")
        if not preview:
            self.add_pass(ALBEDO_PASS, 3, "RGB")
            self.add_pass(NORMAL_PASS, 3, "XYZ")
            if settings.use_denoising:
                self.add_pass(NOISY_PASS, 4, "RGBA")
        # One backend run per view (stereo eyes, multi-view cameras: the scene's "views"), each
        # into its view of the result; a single run without multi-view.
        for index, view in enumerate(view_names):
            if self.cancel_requested():
                return
            if self._render_view(depsgraph, exported, workdir, index, view, rect, width, height) == "cancelled":
                return

    def _denoised(self, combined, aovs, data_passes: dict, settings, depsgraph, folder: Path):
        """Render › Denoise (on by default, as Cycles'): the denoised image, the render itself
        kept as the Noisy Image pass. If denoising cannot run, the render is shown as it is,
        with a warning saying why."""
        self.update_stats("", "Lamina | Denoising")
        t0 = time.perf_counter()
        try:
            if aovs is None:
                raise DenoiseError("the renderer wrote no albedo and normal")
            folder.mkdir(parents=True, exist_ok=True)
            denoised = denoise_image(combined, aovs, settings.samples, folder, depsgraph.scene,
                                     depsgraph.view_layer, bpy.context.preferences)
        except DenoiseError as exc:
            self._renderer_warnings.append(f"Denoise: {exc} (the image is not denoised)")
            return combined
        data_passes[NOISY_PASS] = combined
        print(f"Lamina: denoised in {time.perf_counter() - t0:.2f} s", flush=True)
        return denoised

    def _views(self, depsgraph, camera_object, rect):
        """([view name, ...], {view name: camera}) of a multi-view render, each view's camera
        as Blender places it (its eye: ``camera_model_matrix``, ``camera_shift_x``); ([None],
        None) without multi-view."""
        scene = depsgraph.scene
        if not scene.render.use_multiview or camera_object is None:
            return [None], None
        # The result knows which views Blender renders (Stereo 3D: left and right; Multi-View:
        # the views switched on).
        probe = self.begin_result(0, 0, rect[2], rect[3], layer=depsgraph.view_layer.name)
        names = [v.name for v in probe.views]
        self.end_result(probe, cancel=True)
        if len(names) < 2:
            return [None], None
        views = {}
        for name in names:
            self.active_view_set(name)
            obj = view_camera_object(scene, camera_object, name)
            matrix = self.camera_model_matrix(obj, use_spherical_stereo=False)
            shift = self.camera_shift_x(obj, use_spherical_stereo=False)
            try:
                views[name] = eye_camera_json(obj, scene, matrix, shift)
            except CameraError as exc:               # a panoramic camera
                raise ExportError(f"view '{name}': {exc}") from None
        return names, views

    def _render_view(self, depsgraph, exported, workdir: Path, index: int, view, rect, width: int,
                     height: int) -> str:
        """Render one view (None: the scene's camera) into the result; "cancelled" or "done"."""
        scene = depsgraph.scene
        settings = scene.lamina
        preview = self.is_preview
        if view is not None:
            self.active_view_set(view)
        partial = workdir / f"partial-{index}.npy"
        # Material previews always render here; F12 and animation frames go to the cluster
        # when one is set (the backend child process is its client: no Dask in Blender).
        cluster = "" if preview else settings.cluster.strip()
        extra = (["--cluster", cluster] if cluster else []) + (["--view", view] if view is not None else [])
        cmd = render_command(python_executable(), exported.path, workdir / f"render-{index}.exr", partial,
                             workers=0 if cluster else (PREVIEW_WORKERS if preview else settings.workers),
                             partial_interval=0.5 if preview else settings.update_interval,
                             extra=extra or None)
        # One view layer per render() call: write into that layer (and view) of the result.
        result = self.begin_result(0, 0, rect[2], rect[3], layer=depsgraph.view_layer.name,
                                   view=view or "")
        try:
            status = self._run(cmd, result, partial, rect, height, exported,
                           warm_purpose=None if cluster else ("preview" if preview else "final"))
        except BaseException:
            self.end_result(result, cancel=True)
            raise
        if status == "cancelled":
            self.end_result(result)
            return status
        combined = load_npy(partial)
        if combined is None or combined.shape[:2] != (height, width):
            self.end_result(result, cancel=True)
            raise RenderFailure("the renderer finished without writing an image")
        aovs = load_npy(partial.with_suffix(".aovs.npy"))
        if aovs is not None and aovs.shape[:2] != (height, width):
            aovs = None
        data_passes = {}
        for _, label, _, _ in ([] if preview else requested_passes(depsgraph.view_layer)):
            image = load_npy(pass_npy_path(partial, label))
            if image is not None and image.shape[:2] == (height, width):
                data_passes[label] = image
        if not preview and settings.use_denoising:
            combined = self._denoised(combined, aovs, data_passes, settings, depsgraph, workdir / f"denoise-{index}")
        fill_passes(result, combined, aovs, rect, height, data_passes)
        self.end_result(result)
        return "done"

    def _run(self, cmd, result, partial: Path, rect, height: int, exported=None, warm_purpose=None) -> str:
        env = child_environment(user_environment())
        job = None
        if warm_purpose is not None and keep_renderer_warm():
            # A warm render server (render_server.py) renders it: no interpreter start, no
            # kernel load. cmd is [python, -m, backend, render, arguments...].
            job = POOL.job_for(warm_purpose, cmd[0], env, cmd[4:])
        self.job = job = job or BackendJob(cmd, env=env)
        error = None
        describe = exported.describe if exported is not None else (lambda text: text)
        warnings = self._renderer_warnings
        last_partial = None
        while True:
            for event in job.poll(0.1):
                kind = event.get("event")
                if kind == "progress":
                    self._progress(event)
                elif kind == "partial":
                    image = load_npy(Path(event.get("path", partial)))
                    if image is not None and image.shape[0] == height:
                        last_partial = image
                        fill_passes(result, image, None, rect, height)
                        self.update_result(result)
                elif kind == "warning":
                    warnings.append(describe(str(event.get("message", ""))))
                elif kind == "error":
                    error = describe(str(event.get("message", "render failed")))
                elif kind == "compiling":
                    # First render after installing or updating: the kernels compile once. Said on
                    # the console too: under `blender -b` (a farm node) the status bar is not seen.
                    print("Lamina: compiling render kernels (first run only, about a minute) ...",
                          flush=True)
                    self.update_stats("", "Lamina | Compiling render kernels (first run only)")
                elif kind == "compiled":
                    seconds = float(event.get("seconds", 0.0))
                    print(f"Lamina: compiled render kernels in {seconds:.1f} s", flush=True)
                    self.update_stats("", f"Lamina | Compiled render kernels in {seconds:.1f} s")
                elif kind == "start":
                    self.update_stats("", f"Lamina | Rendering {event.get('width')}×{event.get('height')}, "
                                          f"{event.get('spp')} samples, {event.get('workers')} workers")
            if self.cancel_requested():
                job.cancel()
                if last_partial is None:
                    image = load_npy(partial)
                    if image is not None and image.shape[0] == height:
                        fill_passes(result, image, None, rect, height)
                return "cancelled"
            if job.finished():
                break
        code = job.wait()
        if error is None and code != 0:
            error = describe(job.failure_message())
        if error is not None:
            if last_partial is not None:
                # The result already shows that image (update_result merged it); say that it
                # is partial, so it is neither mistaken for the finished render nor thrown away.
                raise RenderFailure(f"{error} (the image shows the last partial result)")
            raise RenderFailure(error)
        return "done"

    def _progress(self, event: dict) -> None:
        fraction = float(event.get("fraction", 0.0))
        self.update_progress(min(max(fraction, 0.0), 1.0))
        if self.is_preview:
            return
        self.update_stats("", progress_text(event))


def progress_text(event: dict) -> str:
    """The status bar during a render: samples per pixel done (within a round too: the backend's
    ``samples``), elapsed and remaining time."""
    total = int(event.get("total", 0))
    samples = float(event.get("samples", event.get("done", 0)))
    shown = min(int(samples + 1e-6), total) if total else int(samples)
    elapsed = _format_seconds(event.get("elapsed", 0.0))
    eta = _format_seconds(event.get("eta", 0.0))
    return f"Lamina | Sample {shown}/{total} | Time {elapsed} | Remaining {eta}"


CLASSES = (LaminaRenderEngine,)

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    _register_classes()
    atexit.register(POOL.stop_all)


def unregister():
    POOL.stop_all()                    # the warm renderer processes end with the add-on
    atexit.unregister(POOL.stop_all)
    _unregister_classes()
