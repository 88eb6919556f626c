"""Limits on what a scene (and the command line) may ask for, in one place.

Every limit here is checked when a scene is *loaded*, so ``validate`` and ``render`` accept
exactly the same scenes (the command-line options that ``render`` adds are checked against the
same numbers). Each exists because something past it either fails deep inside the renderer (a
recursion, an allocation, an overflow to Inf) or takes unbounded time. docs/scene-format.md
("Limits") and docs/cli.md list them for users.
"""
from __future__ import annotations

import os

# --------------------------------------------------------------------------- documents
#: Nesting of JSON arrays/objects in a scene, material or preset file. A real scene needs about
#: 12 (a nested layered stack with a textured parameter); Python's JSON reader itself recurses
#: and fails near 1000.
MAX_JSON_DEPTH = 64
#: Digits of an integer literal. Python refuses to convert more than 4300 digits, and any
#: integer above ~1e308 cannot become a float; no field needs more than 19 digits.
MAX_INT_DIGITS = 300
#: Length of a field name or value quoted back in an error message (the rest is elided).
MAX_ECHO = 60

# --------------------------------------------------------------------------- numbers
#: Magnitude of any number a field does not bound more tightly (colours, powers, strengths,
#: sizes, IOR, …). Far beyond any physical scene, yet small enough that the products the
#: renderer forms (colour × power × 1/r² × …) stay finite in float64.
MAX_NUMBER = 1e30
#: Magnitude of a coordinate: matrix entries, mesh positions, and every world-space vertex
#: (geometry is traced in float32, whose range ends at 3.4e38; squared distances must fit).
MAX_COORDINATE = 1e12

# --------------------------------------------------------------------------- materials
#: Levels of ``layered`` materials inside each other (1 = a stack without nested stacks).
MAX_LAYER_NESTING = 3
#: Interfaces in one layered material, nested stacks counted by their own interfaces: the
#: compiled stack table's room (MAX_INTERFACES in backend/kernels/layered/table.py, which imports
#: nothing above the kernels; tests/test_robustness.py holds the two equal).
MAX_STACK_INTERFACES = 16

# --------------------------------------------------------------------------- files
#: Length of a file path given in a scene (characters), and of each of its components (bytes
#: in UTF-8, the common file-system limit).
MAX_PATH_LENGTH = 4096
MAX_PATH_COMPONENT = 255

# --------------------------------------------------------------------------- rendering
MAX_SPP = 1 << 24
MAX_BOUNCES = 1024
#: Next-event samples per light at a glossy vertex (render.glossy_light_samples): each is a shadow
#: ray, and the shadow-ray queue is sized for this many per light (at most 4 lights are sampled
#: together), so the queue stays within 32 rays per lane.
MAX_GLOSSY_LIGHT_SAMPLES = 8
MAX_SEED = 2 ** 63 - 1
MAX_FILM_SIDE = 65536
MAX_WORKERS = 64
#: Worker-process losses a render survives (their items are redone); one more stops it.
MAX_WORKER_LOSSES = 3

#: Peak bytes per film pixel of a render: the float64 accumulators (112 B), the pixel index
#: arrays and the output passes assembled for the EXR writer. Measured (ru_maxrss of
#: `render` of an empty scene at --resolution 2000x2000 and 4000x4000, minus the 16x16 run):
#: 430 and 417 B per pixel; with a margin for the scene itself.
FILM_BYTES_PER_PIXEL = 500


#: Peak bytes per (instanced) triangle of loading and rendering a scene: per-corner positions,
#: normals and UVs, their float64 temporaries while flattening, embree's BVH. Measured
#: (benchmarks/worker_memory.py): 3.37 M triangles peak at 2.64 GiB, 841 B per triangle.
SCENE_BYTES_PER_TRIANGLE = 900


#: Loading a light and building its tables, measured on the development host (2-core EPYC;
#: point lights, 20 000 and 100 000 of them, ru_maxrss and wall): 4.4 KiB and 87-99 µs each
#: (the issue's 10^6 lights: 4.2 GiB, 84 s).
LIGHT_BYTES = 4500
LIGHT_LOAD_SECONDS = 90e-6
#: Loading and building one triangle (a 1 M and a 3 M triangle mesh, BVH included): 1.3-1.6 µs.
TRIANGLE_LOAD_SECONDS = 1.6e-6
#: A scene estimated above this gets a warning with the memory and load time before it loads.
HEAVY_SCENE_BYTES = 2 << 30


def heavy_scene_message(triangles: int, lights: int) -> str | None:
    """The warning for a scene whose triangles (instances counted) and lights will take several
    GiB to load and render, with the estimate; None for a smaller one."""
    need = int(triangles) * SCENE_BYTES_PER_TRIANGLE + int(lights) * LIGHT_BYTES
    if need < HEAVY_SCENE_BYTES:
        return None
    seconds = triangles * TRIANGLE_LOAD_SECONDS + lights * LIGHT_LOAD_SECONDS
    have = available_memory()
    return (f"{triangles} triangles (instances counted) and {lights} lights: loading will take "
            f"about {_gib(need)} of memory" + (f" (of {_gib(have)} available)" if have else "")
            + f" and about {seconds:.0f} s")


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation without swapping (Linux: MemAvailable), or
    the physical memory elsewhere; None when unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def film_memory(width: int, height: int) -> int:
    return int(width) * int(height) * FILM_BYTES_PER_PIXEL


def film_memory_problem(width: int, height: int) -> str | None:
    """Why a width × height film cannot be rendered on this machine, or None if it can."""
    need = film_memory(width, height)
    have = available_memory()
    if have is None or need <= have:
        return None
    side = int((have / FILM_BYTES_PER_PIXEL) ** 0.5)
    return (f"a {width} × {height} film needs about {_gib(need)} of memory to render, "
            f"this machine has {_gib(have)} available (about {side} × {side} pixels would fit)")


def geometry_memory_problem(triangles: int) -> str | None:
    """Why a scene of ``triangles`` (instances counted) cannot be loaded here, or None."""
    need = int(triangles) * SCENE_BYTES_PER_TRIANGLE
    have = available_memory()
    if have is None or need <= have:
        return None
    return (f"the objects hold {triangles} triangles (instances counted), which need about "
            f"{_gib(need)} of memory, this machine has {_gib(have)} available")


def _gib(n: float) -> str:
    return f"{n / 2 ** 30:.1f} GiB" if n >= 2 ** 30 else f"{n / 2 ** 20:.0f} MiB"


def cpu_count() -> int:
    """Cores this process may run on (affinity-aware where the platform tells)."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def short(text: str, most: int = MAX_ECHO) -> str:
    """``text`` cut to ``most`` characters with an ellipsis and the full length noted."""
    text = str(text)
    if len(text) <= most:
        return text
    return f"{text[:most - 1]}… ({len(text)} characters)"
