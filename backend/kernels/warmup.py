"""Compile every render kernel by rendering a tiny built-in scene that uses each material kind,
each light kind and each integrator path (camera rays, hits, escapes, deferred layered lanes,
shadow rays). Called once per process before rendering (``cache.ensure_compiled``); with a warm
cache it only loads machine code."""
from __future__ import annotations

import numpy as np


def _quad(z, s=1.0):
    return {"positions": [[-s, -s, z], [s, -s, z], [s, s, z], [-s, s, z]], "indices": [[0, 1, 2], [0, 2, 3]]}


def scene_dict() -> dict:
    eye = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]
    frame = [[0.5, 0.5, -1], [0.5, -0.5, -1], [-0.5, -0.5, -1], [-0.5, 0.5, -1]]
    materials = {
        "diffuse": {"type": "diffuse", "color": [0.5, 0.5, 0.5]},
        "metal": {"type": "conductor", "metal": "Au", "roughness": 0.2},
        "mirror": {"type": "conductor", "metal": "Ag", "roughness": 0.0, "distribution": "beckmann"},
        "glass": {"type": "dielectric", "ior": 1.5, "roughness": 0.1},
        "smooth": {"type": "dielectric", "ior": 1.5, "roughness": 0.0},
        "lamp": {"type": "emission", "color": [1, 1, 1], "strength": 2.0},
        "coat": {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.05},
                                                   {"type": "diffuse", "color": [0.5, 0.2, 0.1]}],
                 "media": [{"thickness": 1.0, "sigma_t": 0.5, "albedo": 0.5}]},
    }
    names = list(materials)
    meshes = {f"q{i}": _quad(-0.1 * i, 1.0 + 0.2 * i) for i in range(len(names))}
    objects = [{"name": n, "mesh": f"q{i}", "materials": [n]} for i, n in enumerate(names)]
    lights = [{"type": "point", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]],
               "power": 10.0}]
    return {"format": "lamina-scene", "version": 1, "film": {"width": 4, "height": 4},
            "camera": {"type": "perspective", "to_world": eye, "frame": frame},
            "render": {"spp": 2, "max_bounces": 3, "seed": 1}, "materials": materials,
            "meshes": meshes, "objects": objects, "lights": lights,
            "world": {"type": "constant", "color": [0.2, 0.2, 0.2]}}


def warm_up() -> None:
    from ..geometry.accel import Accelerator
    from ..integrator import PathTracer
    from ..scene.loader import load_scene_data
    scene = load_scene_data(scene_dict(), "<kernel warm-up>")
    tracer = PathTracer(scene, Accelerator(scene.soup))
    rng = np.random.default_rng(0)
    tracer.render(np.arange(16, dtype=np.int64), 2, rng, 0)
