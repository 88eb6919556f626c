"""Render › Denoise (addon/engine/denoise.py): F12 renders of one small scene with and without it."""
from __future__ import annotations

from pathlib import Path

import bpy

from . import build


def _scene():
    sc = build.scene()
    build.camera()
    build.plane("Floor", size=6.0, material=build.diffuse_material("Grey", (0.6, 0.6, 0.6)))
    build.uv_sphere("Ball", radius=0.8, material=build.diffuse_material("Red", (0.7, 0.15, 0.1)),
                    location=(0.3, 0.5, 0.8))
    build.light("Lamp", "AREA", (1.0, -1.0, 3.0), energy=300.0, size=0.5)
    build.world_colour((0.05, 0.05, 0.05))
    return sc


def _render(sc, path: Path) -> str | None:
    sc.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    sc.render.image_settings.color_depth = "32"
    sc.render.filepath = str(path)
    sc.render.use_file_extension = False
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError as exc:
        return str(exc)
    return None


def renders(tmp, samples=4, reference_samples=1024):
    """The same scene and seed: denoised, plain, and a reference of many samples (plain)."""
    sc = _scene()
    sc.lamina.samples, sc.lamina.seed = samples, 3
    out = {}
    sc.lamina.use_denoising = True
    out["denoised_error"] = _render(sc, Path(tmp) / "denoised.exr")
    sc.lamina.use_denoising = False
    out["plain_error"] = _render(sc, Path(tmp) / "plain.exr")
    sc.lamina.samples, sc.lamina.seed = reference_samples, 11
    out["reference_error"] = _render(sc, Path(tmp) / "reference.exr")
    out.update(denoised=str(Path(tmp) / "denoised.exr"), plain=str(Path(tmp) / "plain.exr"),
               reference=str(Path(tmp) / "reference.exr"))
    return out
