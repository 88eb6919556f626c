"""What a render worker does with one work item, wherever it runs (this process, a thread, a
worker process, a cluster worker: backend/render.py and backend/cluster.py), and how a failure
inside an item is reported: the scene's tracer set up once per worker (``setup_local``), an item
rendered (``render_item``), and the two exceptions the runners raise to stop or fail a render.

A work item is (key, pixels, spp, seed, sample0) (render.plan_round)."""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path


from . import stats
from .errors import LaminaError

WORKER = {}
#: Said in the message of a failure inside the renderer (an exception no check of the input
#: foresaw); benchmarks/fuzz.py counts a case that ends with it as a failure.
INTERNAL_ERROR = "this is a bug in Lamina"


def scene_from_source(source):
    from .scene.loader import load_scene, load_scene_data
    if isinstance(source, (str, Path)):
        return load_scene(source)
    data, where, base = source
    return load_scene_data(data, where, Path(base) if base else None)


def setup_local(source, options, scene=None, state=None):
    """The tracer of ``scene`` (loaded from ``source`` if None) in ``state`` (default: this
    process's); a cluster worker keeps its own state per scene (backend/cluster.py)."""
    from .geometry.accel import Accelerator
    from .integrator import PathTracer
    if scene is None:
        scene = scene_from_source(source)
        options.apply(scene)
    state = WORKER if state is None else state
    accel = Accelerator(scene.soup)
    state["tracer"] = PathTracer(scene, accel)
    state["accel"] = accel
    return scene


def render_item(item, state=None) -> tuple:
    key, pixels, spp, seed, sample0 = item
    if os.environ.get("LAMINA_TEST_FAULT_DIR"):
        _injected_fault(os.environ["LAMINA_TEST_FAULT_DIR"])
    tracer = (WORKER if state is None else state)["tracer"]
    # No generator: every random number is counter-based, keyed by (seed, pixel, sample,
    # dimension); ``render``'s rng argument is unused (making one cost ~30 µs an item).
    rng = None
    # Per-thread CPU time: items may run on threads of one process (with one thread per worker
    # process it equals the process's time).
    t0 = time.thread_time()
    result = tracer.render(pixels, spp, rng, sample0)
    info = stats.take()
    info["rays"] = info.get("rays", 0) + result.pop("rays")
    info["cpu_time"] = time.thread_time() - t0
    info["paths"] = int(pixels.size) * spp
    return key, result, info


def _injected_fault(folder: str) -> None:
    """Tests only (``LAMINA_TEST_FAULT_DIR``): each file in the folder is one fault, taken by the
    first item that removes it: ``kill*`` SIGKILLs this process, ``segv*`` sends it SIGSEGV,
    ``raise*`` raises an exception. Bounded and deterministic in count."""
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return
    for name in names:
        try:
            os.unlink(os.path.join(folder, name))
        except OSError:
            continue                       # another worker took it
        if name.startswith("kill"):
            os.kill(os.getpid(), signal.SIGKILL)
        elif name.startswith("segv"):
            os.kill(os.getpid(), signal.SIGSEGV)
        elif name.startswith("raise"):
            raise RuntimeError(f"injected fault ({name})")
        return


class Stopped(Exception):
    """A stop request (signal, cancel) arrived while items were outstanding."""


class Failed(Exception):
    """The render cannot go on; the message says why (it becomes ``RenderResult.error``)."""


def failure_text(exc: BaseException) -> str:
    """One line naming an exception raised inside an item and where (no traceback)."""
    if isinstance(exc, LaminaError):
        return str(exc)
    where = ""
    remote = getattr(exc, "__cause__", None)
    text = str(remote) if remote is not None and type(remote).__name__ == "_RemoteTraceback" else ""
    if text:
        import re
        found = re.findall(r'File "([^"]+)", line (\d+)', text)
        if found:
            where = f" at {Path(found[-1][0]).name}:{found[-1][1]}"
    elif exc.__traceback__ is not None:
        import traceback
        frames = traceback.extract_tb(exc.__traceback__)
        if frames:
            where = f" at {Path(frames[-1].filename).name}:{frames[-1].lineno}"
    message = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else ""
    return (f"a render worker failed ({type(exc).__name__}{': ' + message if message else ''}{where}); "
            f"{INTERNAL_ERROR}, please report it with the scene")


def wait_for(future, should_stop, every=None):
    """The future's result, checking for a stop request (and calling ``every``, if given) every
    0.2 s while it is not done."""
    while True:
        if should_stop():
            raise Stopped
        try:
            return future.result(timeout=0.2)
        except TimeoutError:       # concurrent.futures and Dask raise the built-in one
            if every is not None:
                every()
