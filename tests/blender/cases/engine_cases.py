"""Render-engine cases (run inside Blender by tests/blender/test_engine.py)."""
from __future__ import annotations

import json
import os
import stat
import sys
import time
from pathlib import Path

import bpy

from . import build

HERE = Path(__file__).resolve().parent.parent


def _fake_backend(tmp, mode: str) -> str:
    """An executable that runs fake_backend.py; set as the add-on's Backend Python."""
    script = Path(tmp) / f"fake-python-{mode}"
    script.write_text(f"#!/bin/sh\nFAKE_MODE={mode} exec {sys.executable} {HERE / 'fake_backend.py'} \"$@\"\n")
    script.chmod(script.stat().st_mode | stat.S_IEXEC)
    prefs = bpy.context.preferences.addons["lamina"].preferences
    prefs.python_executable = str(script)
    prefs.keep_renderer_warm = False      # the fake speaks render's protocol, not the server's
    return str(script)


def _reset_backend():
    prefs = bpy.context.preferences.addons["lamina"].preferences
    prefs.python_executable = ""
    prefs.keep_renderer_warm = True


def _simple_scene(w=16, h=12):
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = w, h
    build.camera()
    build.plane(material=build.diffuse_material("Grey"))
    build.light("Lamp", "POINT", (0, -1, 3), energy=200.0)
    build.world_colour((0.2, 0.2, 0.2))
    return sc


def _render_to(sc, path: Path, multilayer: bool = True):
    settings = sc.render.image_settings
    if multilayer:
        settings.media_type = "MULTI_LAYER_IMAGE"
    else:
        settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    sc.render.filepath = str(path)
    sc.render.use_file_extension = False
    t0 = time.perf_counter()
    try:
        bpy.ops.render.render(write_still=True)
        error = None
    except RuntimeError as exc:
        error = str(exc)
    return error, time.perf_counter() - t0


def fake_pixels(tmp, border=False, layers=1, cluster=""):
    sc = _simple_scene()
    _fake_backend(tmp, "pixels")
    argv_file = Path(tmp) / "argv.json"
    os.environ["FAKE_ARGV"] = str(argv_file)
    sc.lamina.cluster = cluster
    for i in range(1, layers):
        sc.view_layers.new(f"Layer{i + 1}")
    if border:
        sc.render.use_border = True
        sc.render.use_crop_to_border = False
        sc.render.border_min_x, sc.render.border_max_x = 0.25, 0.75
        sc.render.border_min_y, sc.render.border_max_y = 0.0, 0.5
    out = Path(tmp) / ("fake_border.exr" if border else "fake.exr")
    error, seconds = _render_to(sc, out)
    _reset_backend()
    os.environ.pop("FAKE_ARGV", None)
    argv = json.loads(argv_file.read_text()) if argv_file.is_file() else None
    return {"error": error, "path": str(out), "exists": out.is_file(), "seconds": seconds, "argv": argv}


def fake_compiling(tmp):
    """A render that finds a cold kernel cache: the compile's lines reach the console."""
    sc = _simple_scene()
    _fake_backend(tmp, "compiling")
    error, seconds = _render_to(sc, Path(tmp) / "compiling.exr")
    _reset_backend()
    return {"render_error": error}


def fake_failure(tmp, mode="error"):
    sc = _simple_scene()
    _fake_backend(tmp, mode)
    error, seconds = _render_to(sc, Path(tmp) / f"fail_{mode}.exr")
    _reset_backend()
    # What the image editor shows afterwards: the Render Result, saved as a float EXR.
    shown = Path(tmp) / f"shown_{mode}.exr"
    red_max = None
    try:
        bpy.data.images["Render Result"].save_render(str(shown))
        import OpenImageIO as oiio
        inp = oiio.ImageInput.open(str(shown))
        if inp is not None:
            pixels = inp.read_image(0, 0, 0, 3, oiio.FLOAT)
            inp.close()
            red_max = float(pixels[..., 0].max())
    except (KeyError, RuntimeError):
        pass
    return {"error": error, "seconds": seconds, "red_max": red_max}


def cancel(tmp, after=1.0):
    """Simulated Esc: test_break() turns true ``after`` seconds into the render."""
    from lamina.addon.engine.engine import LaminaRenderEngine
    sc = _simple_scene()
    _fake_backend(tmp, "hang")
    pids_file = Path(tmp) / "fake_pids.json"
    os.environ["FAKE_PIDS"] = str(pids_file)
    start = [None]
    original = LaminaRenderEngine.cancel_requested

    def cancel_requested(self):
        if start[0] is None:
            start[0] = time.perf_counter()
        return time.perf_counter() - start[0] > after and pids_file.exists()

    LaminaRenderEngine.cancel_requested = cancel_requested
    try:
        error, seconds = _render_to(sc, Path(tmp) / "cancel.exr")
        returned = time.perf_counter()
    finally:
        LaminaRenderEngine.cancel_requested = original
        _reset_backend()
    pids = json.loads(pids_file.read_text()) if pids_file.exists() else []
    return {"error": error, "seconds": seconds, "pids": pids,
            "cancel_latency": returned - start[0] - after if start[0] else None}


def real_render(tmp, spp=16, seed=3, layered=False, ies=False):
    """The acceptance scene through LAMINA (write_still) and exported for the CLI: a plane and a
    sphere (the reference 3-layer stack when the backend has layered materials), a directional
    area light, a point light (with an IES profile when supported) and a world colour."""
    import math
    from lamina.addon.export import export_scene
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = 32, 24
    build.camera()
    build.plane(material=build.diffuse_material("Grey"), size=6)
    ball = build.reference_stack(bpy.data.materials.new("Stack")) if layered else \
        build.diffuse_material("Ball", (0.6, 0.3, 0.2))
    build.uv_sphere(material=ball)
    area = build.light("Panel", "AREA", (-1.5, -1.0, 3.0), (0.3, -0.3, 0.0), energy=150.0, size=0.8)
    area.data.lamina.beam_mode = "CONE"
    area.data.lamina.cutoff_angle = math.radians(45)
    area.data.lamina.beam_width = math.radians(20)
    lamp = build.light("Lamp", "POINT", (1.0, -1.0, 3.0), energy=200.0)
    if ies:
        lamp.data.energy = 2.0      # with a profile, power scales the file's candela (docs/lights.md)
        lamp.data.lamina.ies_mode = "FILE"
        lamp.data.lamina.ies_file = str(Path(__file__).resolve().parents[2] / "data" / "ies" /
                                        "erco_defined_spot_lm95.ies")
    build.world_colour((0.2, 0.2, 0.2))
    sc.lamina.samples = spp
    sc.lamina.seed = seed
    sc.lamina.workers = 2
    out = Path(tmp) / "engine.exr"
    error, seconds = _render_to(sc, out, multilayer=False)
    exported = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / "cli_scene")
    return {"error": error, "path": str(out), "scene": str(exported.path), "seconds": seconds}


def corrupt_texture(tmp):
    sc = _simple_scene()
    bad = Path(tmp) / "broken.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n this is not a png")
    mat = bpy.data.materials["Grey"]
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(str(bad), check_existing=False)
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse")
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    sc.lamina.fail_on_missing_textures = True      # a farm's setting (off: magenta and a warning)
    error, seconds = _render_to(sc, Path(tmp) / "corrupt.exr")
    return {"error": error, "seconds": seconds}


def cycles_parity(tmp, spp=512, bounces=4):
    """A diffuse-only scene rendered by Cycles and by Lamina with the same light settings."""
    import math
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = 40, 30
    build.camera(location=(0.0, -6.0, 2.5), target=(0.0, 0.0, 0.6), lens=40)
    build.plane(size=8, material=build.diffuse_material("Floor", (0.8, 0.8, 0.8)))
    build.uv_sphere(material=build.diffuse_material("Ball", (0.7, 0.4, 0.2)), segments=48, rings=24)
    build.light("Point", "POINT", (2.0, -1.5, 3.0), energy=300.0, shadow_soft_size=0.1)
    build.light("Sun", "SUN", (0, 0, 5), (0.6, 0.3, 0.0), energy=1.5, angle=math.radians(3))
    build.light("Area", "AREA", (-2.0, 0.5, 2.5), (0.5, -0.6, 0.0), energy=200.0, shape="RECTANGLE",
                size=1.0, size_y=0.5)
    build.world_colour((0.15, 0.2, 0.3), 1.0)
    out = {}
    # Cycles: path tracing with every limit matched to Lamina (no clamping, no light threshold,
    # no denoising, no adaptive sampling, the same bounce limit for every kind of bounce).
    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    cy.samples = spp
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.light_sampling_threshold = 0.0
    cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = bounces
    cy.seed = 1
    cy.filter_width = 1.5
    sc.render.threads_mode = "FIXED"
    sc.render.threads = 2
    path = Path(tmp) / "cycles.exr"
    out["cycles_error"], out["cycles_seconds"] = _render_to(sc, path, multilayer=False)
    out["cycles"] = str(path)
    sc.render.engine = "LAMINA"
    sc.lamina.samples = spp
    sc.lamina.max_bounces = bounces
    sc.lamina.rr_depth = 64          # Cycles' RR is unbiased too; keep ours out of the way
    sc.lamina.workers = 2
    path = Path(tmp) / "lamina.exr"
    out["lamina_error"], out["lamina_seconds"] = _render_to(sc, path, multilayer=False)
    out["lamina"] = str(path)
    return out


def saved_file_animation(tmp):
    """Like ``blender -b shot.blend -E LAMINA -a``: open a saved .blend and render its frames."""
    sc = _simple_scene()
    sc.lamina.seed = 10
    sc.lamina.use_animated_seed = True
    sc.frame_start, sc.frame_end = 1, 2
    blend = Path(tmp) / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    sc = bpy.context.scene
    sc.render.engine = "LAMINA"                        # what -E LAMINA does
    error, files = render_animation(sc, tmp)
    return {"error": error, "files": files}


def render_animation(sc, tmp):
    """The scene's frames rendered by the fake backend into EXR files: (error or None, files)."""
    _fake_backend(tmp, "pixels")
    settings = sc.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    sc.render.filepath = str(Path(tmp) / "frames" / "f_")
    try:
        bpy.ops.render.render(animation=True)
        error = None
    except RuntimeError as exc:
        error = str(exc)
    _reset_backend()
    return error, sorted(str(p) for p in (Path(tmp) / "frames").glob("f_*"))
