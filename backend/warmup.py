"""The first run's compilation of the render kernels, once per process before rendering
(``ensure_compiled``): a tiny built-in scene that uses each material kind, each light kind and
each integrator path (camera rays, hits, escapes, layered lanes, shadow rays) is rendered, which
compiles every kernel into the kernel cache (backend/kernels/cache.py); the layered lane compiles
in a second process meanwhile (backend/kernels/precompile.py). With a warm cache nothing is
rendered here: each kernel loads its machine code when first called.

Above the kernels on purpose: rendering the warm-up scene needs the scene loader, the
accelerator and the integrator, which all import kernels."""
from __future__ import annotations

import sys
import time

import numpy as np

from .kernels.cache import configure, is_warm, marker
from .kernels.precompile import compile_layered_alongside


# A minimal LM-63 photometry (one horizontal angle, three vertical ones).
_IES = """IESNA:LM-63-2002
TILT=NONE
1 1000 1 3 1 1 2 0.1 0.1 0
1 1 100
0 45 90
0
1000 600 100
"""


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
        # A dielectric over a diffuse body: the closed form (kernels/bsdf/coated_diffuse.py), its
        # table builder included.
        "plastic": {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.3},
                                                      {"type": "diffuse", "color": [0.2, 0.5, 0.3]}],
                    "media": [{"thickness": 1.0, "sigma_t": 0.0}]},
        "coat": {"type": "layered", "estimator": "bi",
                 "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.05},
                                {"type": "diffuse", "color": [0.5, 0.2, 0.1]}],
                 "media": [{"thickness": 1.0, "sigma_t": 0.5, "albedo": 0.5}]},
        # A uniform stack: its table (backend/layered/tabulated.py; a small one, 48 nodes: the
        # warm-up compiles the solver's kernels, it is not there to solve big tables)
        "table": {"type": "layered",
                  "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.3},
                                 {"type": "conductor", "metal": "Cu", "roughness": 0.4}],
                  "media": [{"thickness": 1.0, "sigma_t": 0.5, "albedo": 0.5, "phase": {"type": "hg", "g": 0.3}}]},
        # Every layered stack runs the same compiled code; this one walks more of it (three
        # interfaces, a normal map, fiber microflakes, chromatic extinction, the stochastic pdf).
        "stack": {"type": "layered", "pdf": "stochastic",
                  "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.05, "distribution": "beckmann",
                                  "normal": [0.1, 0.0, 1.0]},
                                 {"type": "dielectric", "ior": 1.2, "roughness": 0.01},
                                 {"type": "conductor", "metal": "Cu", "roughness": 0.05}],
                  "media": [{"sigma_t": 0.5, "albedo": [0.5, 0.7, 0.95],
                             "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, 0.5, 0]}},
                            {"sigma_t": [0.3, 0.5, 0.8], "albedo": 0.9, "phase": {"type": "sggx", "roughness": 0.3}}]},
    }
    names = list(materials)
    meshes = {f"q{i}": _quad(-0.1 * i, 1.0 + 0.2 * i) for i in range(len(names))}
    objects = [{"name": n, "mesh": f"q{i}", "materials": [n]} for i, n in enumerate(names)]
    up = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]
    lights = [{"type": "point", "to_world": up, "power": 10.0},
              {"type": "point", "to_world": up, "power": 10.0, "radius": 0.2},
              {"type": "point", "to_world": up, "power": 10.0, "radius": 0.2, "soft_falloff": True},
              {"type": "spot", "to_world": up, "power": 10.0, "spot_size": 60.0, "ies": {"data": _IES}},
              {"type": "area", "to_world": up, "shape": "rectangle", "size": 0.5, "size_y": 0.3, "power": 5.0},
              {"type": "area", "to_world": up, "shape": "disk", "size": 0.5, "power": 5.0, "spread": 60.0},
              {"type": "area", "to_world": up, "shape": "square", "size": 0.5, "power": 5.0,
               "cutoff_angle": 40.0, "beam_width": 20.0},
              {"type": "area", "to_world": up, "shape": "square", "size": 0.5, "power": 5.0, "spread": 0.0},
              {"type": "sun", "to_world": up, "strength": 1.0, "angle": 2.0}]
    return {"format": "lamina-scene", "version": 1, "film": {"width": 4, "height": 4},
            "camera": {"type": "perspective", "to_world": eye, "frame": frame},
            "render": {"spp": 2, "max_bounces": 3, "seed": 1, "caustic_photons": 1.0}, "materials": materials,
            "meshes": meshes, "objects": objects, "lights": lights,
            "world": {"type": "constant", "color": [0.2, 0.2, 0.2]}}


def _env_world(folder) -> dict:
    """An environment-map world (written to a temporary file: the loader reads images by path)."""
    import OpenImageIO as oiio
    path = f"{folder}/sky.exr"
    pixels = np.linspace(0.1, 2.0, 8 * 4 * 3, dtype=np.float32).reshape(4, 8, 3)
    out = oiio.ImageOutput.create(path)
    out.open(path, oiio.ImageSpec(8, 4, 3, oiio.FLOAT))
    out.write_image(pixels)
    out.close()
    return {"type": "environment", "file": path}


def warm_up() -> None:
    import tempfile

    from .film import FilmAccumulator
    from .geometry.accel import Accelerator
    from .integrator import PathTracer
    from .scene.loader import load_scene_data
    with tempfile.TemporaryDirectory(prefix="lamina-warmup-") as folder:
        for world in (None, _env_world(folder)):
            data = scene_dict()
            if world is not None:
                data["world"] = world
            scene = load_scene_data(data, "<kernel warm-up>")
            tracer = PathTracer(scene, Accelerator(scene.soup))
            pixels = np.arange(16, dtype=np.int64)
            result = tracer.render(pixels, 2, np.random.default_rng(0), 0)
            FilmAccumulator(4, 4).add(pixels, result)


def load_kernels() -> float:
    """Load every compiled kernel into this process now (from a warm cache: no compiling), by
    rendering the warm-up scene once at 4 × 4 pixels; returns the seconds it took. A process
    started ahead of time (the session's and the render server's ``--warm``) calls it so that
    its first real render does not pay the loading."""
    from . import stats
    from .film import FilmAccumulator
    from .geometry.accel import Accelerator
    from .integrator import PathTracer
    from .scene.loader import load_scene_data
    t0 = time.perf_counter()
    scene = load_scene_data(scene_dict(), "<kernel warm-up>")
    tracer = PathTracer(scene, Accelerator(scene.soup))
    pixels = np.arange(16, dtype=np.int64)
    FilmAccumulator(4, 4).add(pixels, tracer.render(pixels, 2, np.random.default_rng(0), 0))
    stats.take()
    return time.perf_counter() - t0


def _print_event(event: dict) -> None:
    print(event["message"], file=sys.stderr, flush=True)


_STATE = {"compiled": False}


def ensure_compiled(on_event=None) -> float:
    """Compile every render kernel once per process, before worker processes start.

    On a cold cache reports ``{"event": "compiling", "message": ...}`` before and
    ``{"event": "compiled", "seconds": s, "message": ...}`` after through ``on_event`` (default:
    one line each on stderr), and marks the folder warm. Returns the seconds spent (0 when warm).
    A warm folder holds every render kernel: nothing is rendered then, each kernel loads its
    machine code when first called (rendering the warm-up scenes cost a material preview 0.8 s of
    its ~1.8 s, measured)."""
    if _STATE["compiled"]:
        return 0.0
    emit = on_event or _print_event
    cold = not is_warm()
    if not cold:
        _STATE["compiled"] = True
        return 0.0
    emit({"event": "compiling", "message": "compiling render kernels (first run only) ..."})
    t0 = time.perf_counter()
    helper = compile_layered_alongside()
    try:
        warm_up()
    finally:
        if helper is not None and helper.poll() is None:
            helper.kill()
            helper.wait()
    elapsed = time.perf_counter() - t0
    _STATE["compiled"] = True
    if cold:
        try:
            marker().write_text(f"{elapsed:.1f}\n")
        except OSError:
            pass
        emit({"event": "compiled", "seconds": round(elapsed, 1),
              "message": f"compiled render kernels in {elapsed:.1f} s (cached in {configure()})"})
    return elapsed if cold else 0.0
