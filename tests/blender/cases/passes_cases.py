"""Data passes and stereo / multi-view, Cycles vs Lamina (run by tests/blender/test_passes_parity.py).

One scene: a smooth UV sphere and a tilted floor with UV maps, object and material pass indices,
world mist; Cycles and Lamina render it with every data pass on, and again as a stereo pair and
as a multi-view pair with per-view cameras (``Cam_L`` / ``Cam_R``)."""
from __future__ import annotations

import math
from pathlib import Path

import bpy

from . import build
from .parity_cases import _match_cycles

DATA_PASSES = ("use_pass_z", "use_pass_mist", "use_pass_normal", "use_pass_position", "use_pass_uv",
               "use_pass_object_index", "use_pass_material_index")


def _scene(width=64, height=48):
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = width, height
    cam = build.camera("Cam", location=(0.4, -6.0, 2.0), target=(0.0, 0.0, 0.6))
    ball_mat = build.diffuse_material("Ball", (0.7, 0.3, 0.2))
    ball_mat.pass_index = 5
    floor_mat = build.diffuse_material("Floor", (0.5, 0.5, 0.5))
    floor_mat.pass_index = 9
    ball = build.uv_sphere("Ball", radius=1.0, segments=32, rings=16, material=ball_mat, location=(0.3, 0.5, 1.0))
    ball.pass_index = 2
    floor = build.plane("Floor", size=6.0, material=floor_mat)
    floor.rotation_euler = (0.15, 0.0, 0.4)
    floor.pass_index = 4
    build.light("Sun", "SUN", rotation=(0.5, 0.2, 0.0), energy=3.0)
    world = build.world_colour((0.2, 0.2, 0.2))
    world.mist_settings.start = 3.0
    world.mist_settings.depth = 6.0
    world.mist_settings.falloff = "QUADRATIC"
    vl = bpy.context.view_layer
    for prop in DATA_PASSES:
        setattr(vl, prop, True)
    return sc, cam


def _render_pair(sc, tmp, name, spp):
    from .engine_cases import _render_to
    out = {}
    _match_cycles(sc, spp, 1)
    path = Path(tmp) / f"{name}_cycles.exr"
    out["cycles_error"], out["cycles_seconds"] = _render_to(sc, path)
    out["cycles"] = str(path)
    sc.render.engine = "LAMINA"
    sc.lamina.samples = spp
    sc.lamina.max_bounces = 1
    sc.lamina.workers = 2
    path = Path(tmp) / f"{name}_lamina.exr"
    out["lamina_error"], out["lamina_seconds"] = _render_to(sc, path)
    out["lamina"] = str(path)
    return out


def data_passes(tmp, spp=16):
    sc, _ = _scene()
    return _render_pair(sc, tmp, "passes", spp)


def stereo(tmp, spp=4, mode="OFFAXIS"):
    sc, cam = _scene()
    sc.render.use_multiview = True
    sc.render.views_format = "STEREO_3D"
    st = cam.data.stereo
    st.convergence_mode = mode
    st.interocular_distance = 0.4
    st.convergence_distance = 5.0
    st.pivot = "CENTER"
    return _render_pair(sc, tmp, f"stereo_{mode.lower()}", spp)


def multiview(tmp, spp=4):
    """Multi-View format: the right view's camera is the object named with its suffix."""
    sc, cam = _scene()
    sc.render.use_multiview = True
    sc.render.views_format = "MULTIVIEW"
    cam.name = "Cam_L"
    right = build.link(bpy.data.objects.new("Cam_R", cam.data.copy()))
    right.data.lens = 35.0
    right.location = (-1.5, -5.5, 2.5)
    right.rotation_euler = cam.rotation_euler.copy()
    right.rotation_euler.z -= math.radians(12)
    bpy.context.view_layer.update()
    return _render_pair(sc, tmp, "multiview", spp)


def stereo_toe(tmp, spp=4):
    return stereo(tmp, spp, "TOE")


def stereo_parallel(tmp, spp=4):
    return stereo(tmp, spp, "PARALLEL")
