"""F12 and material previews through the warm render server (run inside Blender by
tests/blender/test_warm_renderer.py and benchmarks/f12_time.py)."""
from __future__ import annotations

import time
from pathlib import Path

import bpy
import numpy as np

from . import build


def small_scene(width=320, height=180, spp=32):
    """A small everyday scene: Principled ground, a Principled sphere, a cube, a sun and a
    world colour (Blender's defaults where the case does not say otherwise)."""
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = width, height
    build.camera()
    ground = bpy.data.materials.new("Ground")
    ground.use_nodes = True
    build.plane(material=ground, size=8)
    ball = bpy.data.materials.new("Ball")
    ball.use_nodes = True
    ball.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.6, 0.1, 0.1, 1)
    build.uv_sphere(material=ball, location=(-0.8, 0, 1))
    cube = build.mesh_object("Cube", [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)],
                             [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)],
                             material=ground, location=(0.6, -0.3, 0))
    cube.scale = (0.9, 0.9, 0.9)
    build.light("Sun", "SUN", (0, 0, 5), (0.6, 0.2, 0.8), energy=3.0)
    build.world_colour((0.05, 0.07, 0.1))
    sc.lamina.samples = spp
    sc.cycles.samples = spp
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.use_denoising = False
    sc.cycles.device = "CPU"
    return sc


def _render(sc, engine: str, path: Path):
    sc.render.engine = engine
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.filepath = str(path)
    sc.render.use_file_extension = False
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - t0


def _server_pid():
    from lamina.addon.engine.render_server import POOL
    server = POOL.servers.get("final")
    return server.job.proc.pid if server is not None and server.alive else None


def _pixels(path):
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(path))
    px = inp.read_image(0, 0, 0, 4, oiio.FLOAT)
    inp.close()
    return np.asarray(px)


def timings(tmp, rounds=4, width=320, height=180, spp=32, cycles=True):
    """Wall time of F12 (write_still) for Lamina through its warm server (the first F12 starts the
    server and is reported apart), Lamina with a new process per render (keep_renderer_warm off)
    and Cycles, interleaved round by round."""
    sc = small_scene(width, height, spp)
    prefs = bpy.context.preferences.addons["lamina"].preferences
    sc.render.threads_mode = "AUTO"
    out = {"first_warm": None, "warm": [], "cold": [], "cycles": []}
    prefs.keep_renderer_warm = True
    out["first_warm"] = _render(sc, "LAMINA", Path(tmp) / "first.exr")
    if cycles:
        _render(sc, "CYCLES", Path(tmp) / "cycles-first.exr")      # Cycles' own first-render costs
    for i in range(rounds):
        order = ["warm", "cold", "cycles"] if i % 2 == 0 else ["cycles", "cold", "warm"]
        for kind in order:
            if kind == "cycles" and not cycles:
                continue
            prefs.keep_renderer_warm = kind != "cold"
            engine = "CYCLES" if kind == "cycles" else "LAMINA"
            out[kind].append(_render(sc, engine, Path(tmp) / f"{kind}-{i}.exr"))
    prefs.keep_renderer_warm = True
    return out


def warm_same_as_cold(tmp, spp=8):
    """Two F12s through the server and one in a new process: the same pixels (same seed), and the
    server's process is the same for both warm renders."""
    sc = small_scene(96, 54, spp)
    prefs = bpy.context.preferences.addons["lamina"].preferences
    prefs.keep_renderer_warm = True
    _render(sc, "LAMINA", Path(tmp) / "w1.exr")
    pid1 = _server_pid()
    _render(sc, "LAMINA", Path(tmp) / "w2.exr")
    pid2 = _server_pid()
    prefs.keep_renderer_warm = False
    _render(sc, "LAMINA", Path(tmp) / "c.exr")
    prefs.keep_renderer_warm = True
    w1, w2, c = (_pixels(Path(tmp) / n) for n in ("w1.exr", "w2.exr", "c.exr"))
    return {"pid1": pid1, "pid2": pid2, "warm_equal": bool(np.array_equal(w1, w2)),
            "cold_equal": bool(np.array_equal(w1, c)), "mean": float(w1[:, :, :3].mean())}


def warm_cancel(tmp, after=0.7):
    """Esc during a warm F12: the render returns promptly, the server stays alive and renders the
    next F12."""
    from lamina.addon.engine.engine import LaminaRenderEngine
    sc = small_scene(320, 180, 4096)
    start = [None]
    original = LaminaRenderEngine.cancel_requested

    def cancel_requested(self):
        if start[0] is None:
            start[0] = time.perf_counter()
        return time.perf_counter() - start[0] > after

    LaminaRenderEngine.cancel_requested = cancel_requested
    try:
        t0 = time.perf_counter()
        try:
            _render(sc, "LAMINA", Path(tmp) / "cancelled.exr")
            error = None
        except RuntimeError as exc:
            error = str(exc)
        seconds = time.perf_counter() - t0
    finally:
        LaminaRenderEngine.cancel_requested = original
    pid1 = _server_pid()
    sc.lamina.samples = 4
    t1 = time.perf_counter()
    _render(sc, "LAMINA", Path(tmp) / "after.exr")
    return {"error": error, "seconds": seconds, "pid_after_cancel": pid1, "pid_next": _server_pid(),
            "next_seconds": time.perf_counter() - t1,
            "next_mean": float(_pixels(Path(tmp) / "after.exr")[:, :, :3].mean())}



def _preview_of(mat, timeout=240.0):
    """Seconds until a material's preview shows pixels, and until it stops changing."""
    from .preview_cases import generate_preview
    t0 = time.perf_counter()
    generate_preview(mat)
    first = px = None
    while time.perf_counter() - t0 < timeout:
        w, h = mat.preview.image_size
        if w:
            now = np.array(mat.preview.image_pixels_float[:], dtype=np.float32).reshape(h, w, 4)
            if first is None and now[:, :, :3].max() > 0:
                first = time.perf_counter() - t0
            if px is not None and first is not None and np.array_equal(now, px) and \
                    time.perf_counter() - t0 - last > 1.5:
                break
            if px is None or not np.array_equal(now, px):
                px, last = now, time.perf_counter() - t0
        time.sleep(0.02)
    w, h = mat.preview.image_size
    return {"first_pixels": first, "final": last if px is not None else None, "size": [w, h],
            "mean": float(px[:, :, :3].mean()) if px is not None else None}


def previews(tmp, count=3):
    """Material previews one after the other (the first starts the preview server)."""
    build.scene()
    out = []
    for i in range(count):
        mat = build.diffuse_material(f"Preview{i}", (0.8, 0.2 + 0.2 * i, 0.1))
        mat.preview_render_type = "SPHERE"
        out.append(_preview_of(mat))
    from lamina.addon.engine.render_server import POOL
    server = POOL.servers.get("preview")
    return {"previews": out, "server_jobs": server.jobs_done if server is not None else None}
