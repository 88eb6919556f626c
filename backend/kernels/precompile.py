"""The layered lane compiled in a process of its own, alongside the render process's first
compilation (about 30 % of it): the argument types the shading kernel calls it with, the helper
process, and the wait before the shading kernel links it (kernels/jit.py)."""
from __future__ import annotations

import os
import subprocess
import sys

from . import jit
from .cache import BACKEND, configure, user_cache_root

#: Seconds the render process waits for the layered lane from the helper process before it
#: compiles the lane itself.
HELPER_TIMEOUT = 600.0


def compile_layered_alongside():
    """Start a second process that compiles the layered lane (≈ 30 % of the first compilation:
    22 of 71 s CPU in one process on the 2-core AMD host, 2026-12-04) into the same cache while
    this one compiles the rest; this process waits for it where the shading kernel calls the
    lane, then loads it from the cache. With one core, ``LAMINA_SERIAL_COMPILE=1``, or if the
    process cannot start: None, and this process compiles everything (the same machine code
    either way)."""
    if os.environ.get("LAMINA_SERIAL_COMPILE") or (os.cpu_count() or 1) < 2:
        return None
    from .layered import batch
    env = dict(os.environ, LAMINA_KERNEL_CACHE=str(user_cache_root()), LAMINA_SERIAL_COMPILE="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(BACKEND.parent), env.get("PYTHONPATH")]))
    try:
        helper = subprocess.Popen(
            [sys.executable, "-c", "from backend.kernels.precompile import precompile_layered; precompile_layered()"],
            env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None

    def wait():
        try:
            helper.wait(timeout=HELPER_TIMEOUT)
        except subprocess.TimeoutExpired:
            helper.kill()
            helper.wait()

    jit.compiled_elsewhere(batch.shade_lane, wait)
    return helper


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
    from .workitems import WalkScratch
    TX = empty_textures()
    vec3 = types.UniTuple(types.float64, 3)
    asks = typeof(batch.LaneAsks(*(False,) * len(batch.LaneAsks._fields)))
    return (typeof(empty_table(TX)), typeof(TX), types.int64, types.float64, types.float64,
            types.UniTuple(types.float64, 6), vec3, vec3, asks, types.uint64, types.int64,
            typeof(WalkScratch(*batch.scratch(2))))


def precompile_layered() -> None:
    """Compile the layered lane (about 30 % of the first compilation) into the kernel cache, in a
    process of its own that runs while the render process compiles the rest (kernels/cache.py)."""
    configure()
    from .layered import batch
    batch.shade_lane.compile(layered_lane_signature())
