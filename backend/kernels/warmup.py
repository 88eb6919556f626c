"""Compile every render kernel by rendering a tiny built-in scene that uses each material kind,
each light kind and each integrator path (camera rays, hits, escapes, layered lanes, shadow
rays). Called once per process before rendering (``cache.ensure_compiled``); with a warm
cache it only loads machine code."""
from __future__ import annotations

import numpy as np


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
        "coat": {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.05},
                                                   {"type": "diffuse", "color": [0.5, 0.2, 0.1]}],
                 "media": [{"thickness": 1.0, "sigma_t": 0.5, "albedo": 0.5}]},
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
            "render": {"spp": 2, "max_bounces": 3, "seed": 1}, "materials": materials,
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

    from ..film import FilmAccumulator
    from ..geometry.accel import Accelerator
    from ..integrator import PathTracer
    from ..scene.loader import load_scene_data
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


def layered_lane_signature() -> tuple:
    """The argument types with which the shading kernel calls the layered lane
    (``kernels/integrator.shade`` → ``layered.batch.shade_lane``). Numba types a table by its
    arrays' dtypes and dimensions, not their contents, so empty tables give the render's types
    without building (or compiling) anything (tests/test_kernels_core.py checks that they are
    the render's). If they ever differ, the render process compiles its own version."""
    from numba import typeof
    from numba.core import types

    from .layered import batch
    from .layered.table import empty_table
    from .textures import empty_table as empty_textures
    TX = empty_textures()
    vec3 = types.UniTuple(types.float64, 3)
    flag = types.boolean
    return (typeof(empty_table(TX)), typeof(TX), types.int64, types.float64, types.float64,
            types.UniTuple(types.float64, 6), vec3, vec3, flag, flag, flag, flag, flag, flag, types.uint64,
            types.int64,
            *(typeof(a) for a in batch.scratch(2)))


def precompile_layered() -> None:
    """Compile the layered lane (about 30 % of the first compilation) into the kernel cache, in a
    process of its own that runs while the render process compiles the rest (kernels/cache.py)."""
    from .cache import configure
    configure()
    from .layered import batch
    batch.shade_lane.compile(layered_lane_signature())
