"""The ``LAMINA`` render engine: export → backend child process → Render Result.

Works for F12, animations, ``blender -b file.blend -E LAMINA -f 1`` / ``-a`` and material
previews. Everything that goes wrong ends in ``report({'ERROR'})`` + ``error_set`` (so
``bpy.ops.render.render`` raises in background mode) — never in a silent black image.
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
import traceback
from pathlib import Path

import bpy

from .. import preferences
from ..export import export_scene
from ..export.camera import border_rect, film_size
from ..export.scene import ExportError
from .job import BackendJob, child_environment, render_command
from .pixels import ALBEDO_PASS, NORMAL_PASS, fill_passes, load_npy
from . import viewport

PREVIEW_WORKERS = 1          # worker processes cost ~1 s to start; thumbnails are small


class RenderFailure(Exception):
    """A failure with a message meant for the user."""


def _python() -> str:
    prefs = preferences.get()
    if prefs is not None and prefs.python_executable:
        return bpy.path.abspath(prefs.python_executable)
    return sys.executable


def _preview_samples() -> int:
    prefs = preferences.get()
    return int(prefs.preview_samples) if prefs is not None else 16


def _keep_files() -> bool:
    prefs = preferences.get()
    return bool(prefs and prefs.keep_files)


def _user_env() -> dict:
    """Where the backend finds user presets and caches its compiled kernels: the extension's user
    folder (never the install folder, which an update replaces and may be read-only), unless
    LAMINA_KERNEL_CACHE is set in Blender's own environment."""
    env = {}
    try:
        env["LAMINA_PRESET_PATH"] = bpy.utils.extension_path_user(preferences.ADDON_ID, path="presets",
                                                                  create=False)
        if not os.environ.get("LAMINA_KERNEL_CACHE"):     # set in Blender's environment, it wins
            env["LAMINA_KERNEL_CACHE"] = bpy.utils.extension_path_user(preferences.ADDON_ID, path="kernels",
                                                                       create=True)
    except (ValueError, RuntimeError, TypeError):   # not installed as an extension (development)
        pass
    return env


def _format_seconds(seconds: float) -> str:
    seconds = max(0.0, float(seconds))
    if seconds < 60:
        return f"{seconds:.1f} s"
    m, s = divmod(int(round(seconds)), 60)
    if m < 60:
        return f"{m}:{s:02d}"
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}"


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

    # ------------------------------------------------------------------ render

    def render(self, depsgraph):
        workdir = Path(tempfile.mkdtemp(prefix="lamina-"))
        keep = False
        self._exported = None
        self._renderer_warnings: list[str] = []
        try:
            keep = _keep_files() and not self.is_preview
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
        asked, by Blender name (object, material, node...)."""
        exported = getattr(self, "_exported", None)
        if exported is None or self.is_preview:
            return
        text = exported.warning_text(extra=self._renderer_warnings)
        self._exported = None                    # once per render
        if text:
            print(text, file=sys.stderr)
            self.report({"WARNING"}, text)

    def _fail(self, message: str) -> None:
        message = f"Lamina: {message}"
        print(message, file=sys.stderr)
        if self.is_preview:
            return                               # thumbnails fail quietly (console only)
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
        exported = export_scene(depsgraph, workdir / "scene",
                                camera_object=self.camera_override or scene.camera,
                                samples=_preview_samples() if preview else None,
                                seed_offset=seed_offset, preview=preview)
        self._exported = exported                # its notes are reported with the renderer's, once
        if not preview:
            print(f"Lamina: exported {exported.stats['triangles']} triangles "
                  f"({exported.stats['meshes']} meshes, {exported.stats['instances']} instances) "
                  f"in {time.perf_counter() - t0:.2f} s")
        if self.cancel_requested():
            return

        partial = workdir / "partial.npy"
        # Material previews always render here; F12 and animation frames go to the cluster
        # when one is set (the backend child process is its client: no Dask in Blender).
        cluster = "" if preview else settings.cluster.strip()
        cmd = render_command(_python(), exported.path, workdir / "render.exr", partial,
                             workers=0 if cluster else (PREVIEW_WORKERS if preview else settings.workers),
                             partial_interval=0.5 if preview else settings.update_interval,
                             extra=["--cluster", cluster] if cluster else None)
        if not preview:
            self.add_pass(ALBEDO_PASS, 3, "RGB")
            self.add_pass(NORMAL_PASS, 3, "XYZ")
        # One view layer per render() call: write into that layer of the result.
        result = self.begin_result(0, 0, rect[2], rect[3], layer=depsgraph.view_layer.name)
        try:
            status = self._run(cmd, result, partial, rect, height, exported)
        except BaseException:
            self.end_result(result, cancel=True)
            raise
        if status == "cancelled":
            self.end_result(result)
            return
        combined = load_npy(partial)
        if combined is None or combined.shape[:2] != (height, width):
            self.end_result(result, cancel=True)
            raise RenderFailure("the renderer finished without writing an image")
        aovs = load_npy(partial.with_suffix(".aovs.npy"))
        if aovs is not None and aovs.shape[:2] != (height, width):
            aovs = None
        fill_passes(result, combined, aovs, rect, height)
        self.end_result(result)

    def _run(self, cmd, result, partial: Path, rect, height: int, exported=None) -> str:
        env = child_environment(_user_env())
        self.job = job = BackendJob(cmd, env=env)
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
                    # First render after installing or updating: the kernels compile once.
                    self.update_stats("", "Lamina | Compiling render kernels (first run only)")
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


register, unregister = bpy.utils.register_classes_factory(CLASSES)
