"""Benchmark scenes built in code (dicts in the scene format), shared by benchmark scripts."""
from __future__ import annotations


def _m(tx=0.0, ty=0.0, tz=0.0, s=1.0):
    return [[s, 0, 0, tx], [0, s, 0, ty], [0, 0, s, tz], [0, 0, 0, 1]]


def _quad(p0, p1, p2, p3):
    """Inline mesh of one quad (counter-clockwise seen from the front)."""
    return {"positions": [p0, p1, p2, p3], "indices": [[0, 1, 2], [0, 2, 3]]}


def cornell_box(width=256, height=256, spp=16, max_bounces=6, area_light=True) -> dict:
    """A Cornell-like room 2 m wide (x ∈ [-1, 1], y ∈ [-1, 1], z ∈ [0, 2]), open towards −Y where the
    camera stands, with a rough conductor sphere and a dielectric sphere and a ceiling light."""
    meshes = {
        "floor": _quad([-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]),
        "ceiling": _quad([-1, -1, 2], [-1, 1, 2], [1, 1, 2], [1, -1, 2]),
        "back": _quad([-1, 1, 0], [1, 1, 0], [1, 1, 2], [-1, 1, 2]),
        "left": _quad([-1, -1, 0], [-1, 1, 0], [-1, 1, 2], [-1, -1, 2]),
        "right": _quad([1, -1, 0], [1, -1, 2], [1, 1, 2], [1, 1, 0]),
        "sphere": {"shape": "sphere", "radius": 0.4, "segments": 96},
    }
    materials = {
        "white": {"type": "diffuse", "color": [0.73, 0.73, 0.73]},
        "red": {"type": "diffuse", "color": [0.63, 0.065, 0.05]},
        "green": {"type": "diffuse", "color": [0.14, 0.45, 0.091]},
        "gold": {"type": "conductor", "metal": "Au", "roughness": 0.1},
        "glass": {"type": "dielectric", "ior": 1.5, "roughness": 0.0},
    }
    objects = [
        {"name": "floor", "mesh": "floor", "materials": ["white"]},
        {"name": "ceiling", "mesh": "ceiling", "materials": ["white"]},
        {"name": "back", "mesh": "back", "materials": ["white"]},
        {"name": "left", "mesh": "left", "materials": ["red"]},
        {"name": "right", "mesh": "right", "materials": ["green"]},
        {"name": "metal ball", "mesh": "sphere", "to_world": _m(-0.45, 0.3, 0.4), "materials": ["gold"]},
        {"name": "glass ball", "mesh": "sphere", "to_world": _m(0.45, -0.2, 0.4), "materials": ["glass"]},
    ]
    lights = []
    if area_light:
        # A 0.5 m square light just below the ceiling, facing down (area lights emit along local −Z).
        lights.append({"type": "area", "to_world": _m(0, 0, 1.98), "shape": "square", "size": 0.5,
                       "power": 60.0, "color": [1, 0.85, 0.7]})
    camera = {"type": "perspective",
              "to_world": [[1, 0, 0, 0], [0, 0, -1, -3.8], [0, 1, 0, 1], [0, 0, 0, 1]],
              "frame": [[0.3, 0.3, -1], [0.3, -0.3, -1], [-0.3, -0.3, -1], [-0.3, 0.3, -1]]}
    return {"format": "lamina-scene", "version": 1,
            "film": {"width": width, "height": height}, "camera": camera,
            "render": {"spp": spp, "max_bounces": max_bounces, "seed": 1},
            "materials": materials, "meshes": meshes, "objects": objects, "lights": lights}
