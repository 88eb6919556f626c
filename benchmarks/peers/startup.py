"""Where Lamina's fixed cost per render goes: the parts of its start-up, measured one by one.

A render (in-process ``backend.render.Renderer``, worker threads: backend/render.py) loads the
scene, builds its embree scene and the integrator's typed tables (materials, lights, textures,
layered stacks) once; the threads share them. This module times those parts in CPU seconds so
that the fitted fixed cost t0 of the series can be read: t0 ≈ load + embree build + tables + the
first work items' warm-up. Cycles' fixed cost (scene sync, BVH build, in one process) is only
available as a whole: the intercept of its CPU time against spp.
"""
from __future__ import annotations

import copy
import time

def lamina_startup(data: dict, workers: int, repeats: int = 3) -> dict:
    """CPU seconds (median of ``repeats``) of one scene load, one embree build and one build of
    the integrator's tables, and their sum (what every render pays once, whatever ``workers``)."""
    from backend.geometry.accel import Accelerator
    from backend.integrator import PathTracer
    from backend.scene.loader import load_scene_data

    def best(f):
        vals = []
        for _ in range(repeats):
            vals.append(f())
        return sorted(vals)[len(vals) // 2]

    def load():
        c0 = time.process_time()
        load_scene_data(copy.deepcopy(data), "<startup>")
        return time.process_time() - c0

    scene = load_scene_data(copy.deepcopy(data), "<startup>")
    accel = Accelerator(scene.soup)

    def build():
        c0 = time.process_time()
        Accelerator(scene.soup)
        return time.process_time() - c0

    def tables():
        c0 = time.process_time()
        PathTracer(scene, accel)
        return time.process_time() - c0

    out = {"scene_load": best(load), "embree_build": best(build), "tables": best(tables)}
    out["predicted_t0"] = out["scene_load"] + out["embree_build"] + out["tables"]
    return out
