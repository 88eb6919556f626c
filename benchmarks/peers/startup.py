"""Where Lamina's fixed cost per render goes: the parts of its start-up, measured one by one.

A render with ``workers`` = N loads the scene in the master, then starts N worker processes
(``spawn``: a fresh interpreter each, importing NumPy, embreex and the backend), each of which
loads the scene again and builds its own embree scene (backend/render.py). This module times
those parts in CPU seconds so that the fitted fixed cost t0 of the series can be read:
t0 ≈ master load + N × (interpreter and imports + load + embree build) + pool overhead.
Cycles' fixed cost (scene sync, BVH build, in one process) is only available as a whole: the
intercept of its CPU time against spp.
"""
from __future__ import annotations

import copy
import resource
import subprocess
import sys
import time

from ..scenes import REPO

#: What a worker process imports before it can render (backend/render.py's worker side).
WORKER_IMPORTS = "import backend.render, backend.integrator, backend.scene.loader, backend.geometry.accel, embreex"


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def lamina_startup(data: dict, workers: int, repeats: int = 3) -> dict:
    """CPU seconds of: one scene load, one embree build, one fresh interpreter with the
    worker's imports (median of ``repeats``), and the sum a render with ``workers`` pays."""
    from backend.geometry.accel import Accelerator
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

    def build():
        c0 = time.process_time()
        Accelerator(scene.soup)
        return time.process_time() - c0

    def interpreter():
        c0 = _children_cpu()
        subprocess.run([sys.executable, "-c", WORKER_IMPORTS], cwd=REPO, check=True)
        return _children_cpu() - c0

    out = {"scene_load": best(load), "embree_build": best(build), "interpreter_imports": best(interpreter)}
    out["predicted_t0"] = out["scene_load"] + workers * (out["interpreter_imports"] + out["scene_load"] + out["embree_build"])
    return out
