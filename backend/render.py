"""Render orchestration: work items, worker processes, exact merging, progress, adaptivity, cancel.

Work is cut into *items* (a band of pixels × a block of sample indices: ``plan_round``) whose
shape depends only on the image, the spp and the merged results so far — never on the worker
count. Every random number is counter-based (keyed by seed, pixel, sample, dimension), each item
is rendered entirely by one worker, and the master adds item results in item order. Hence the
same seed and spp give a bit-identical image for any number of workers (tested).

Schedule (``SCHEDULE``, simulated by benchmarks/parallel_scaling.py): a *pass* gives every active
pixel a block of samples; passes follow each other as one stream of items, with
``items_in_flight(workers)`` items submitted ahead of the one being merged, so workers never wait
for a pass to end and the merge (compiled, in this thread) runs while they trace. Only adaptive
sampling (``noise_target`` > 0) waits: once pixels can have ``min_spp`` samples, each pass is
planned after the one before it is merged, and pixels whose relative standard error of the mean is
below the target leave the plan.

Parallelism (``RenderOptions.parallel``):
* ``"threads"`` (default): worker threads of this process share one scene, one embree BVH and
  one set of compiled kernels. An item's whole bounce loop is one compiled call that releases
  the GIL (backend/kernels/item_loop.py): a render holds the GIL for about 1 % of its CPU time
  (benchmarks/parallel_scaling.py), so threads scale without loading anything twice.
* ``"processes"``: worker processes (an option; since the layered BSDF runs compiled (``nogil``)
  every scene uses threads by default: demo scene at half size, 16 spp, 2 workers, 2.0–2.4 s wall
  with threads against 6.3–8.1 s with processes). On Linux they are forked once this process holds
  the scene and its BVH, and share both; elsewhere they are spawned and each loads the scene
  (``_ProcessItems``).
* ``cluster`` (``RenderOptions.cluster``): Dask tasks on other machines (backend/cluster.py,
  docs/cluster.md); the same items and the same item function, this process only merges.
Kernels are compiled (or loaded from the cache) once, before any worker starts.

Failures (docs/cli.md, "When a worker fails"):
* A worker *process* that dies (SIGKILL, the out-of-memory killer, a crash) is replaced by a new
  one and the item it was on goes back to the queue. Every item is a pure function of its key and
  results are merged in item order, so the image is bit-identical to an undisturbed render. Each
  loss is one warning; after ``MAX_WORKER_LOSSES`` losses the render stops with an error and the
  samples merged so far are kept (``RenderResult.error``). The workers are plain processes with
  one pipe each (``_ProcessItems``), not a ``ProcessPoolExecutor``: its manager thread blocks
  for ever on a result that a killed worker left half-written, and a broken pool can only be
  replaced whole.
* When the stop request came with the loss (SIGTERM to the whole process group, as a farm manager
  or ``timeout`` sends it, kills the workers too), the render stops as interrupted instead.
* An exception inside an item (a worker thread, a worker process, or the serial loop) stops the
  render the same way, with an error naming it: nothing is lost silently.
"""
from __future__ import annotations

import math
import os
import signal
import time
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass, field

import numpy as np

from . import stats
from .errors import LaminaError
from .film import FilmAccumulator
from .limits import MAX_WORKER_LOSSES, MAX_WORKERS
from .mathutil import LUMINANCE
from .work_items import WORKER, Failed, Stopped, failure_text, render_item, setup_local, wait_for

#: Paths per work item. An item's fixed cost is ~0.1 ms (its bounce loop is one compiled call,
#: backend/kernels/item_loop.py) against ~25 ms of tracing at this size, and a render of a
#: 256² image at 128 spp is 512 items: enough for 64 workers to share evenly
#: (benchmarks/parallel_scaling.py simulates the schedule).
LANES_PER_ITEM = 1 << 14
MIN_ITEMS_PER_ROUND = 4    # so that several workers have something to do on small images
#: Items in flight per worker: started or waiting for a worker, and finished but not yet merged
#: (results are merged in item order, so a slow item holds back the merge of the ones after it).
ITEMS_IN_FLIGHT_PER_WORKER = 3


def items_in_flight(workers: int) -> int:
    """How many items a render keeps submitted ahead of its merge point."""
    return max(4, ITEMS_IN_FLIGHT_PER_WORKER * workers)


#: How the master schedules items (read by benchmarks/parallel_scaling.py, which simulates it):
#: passes follow each other without waiting, ``items_in_flight(workers)`` items ahead of the
#: merge point; only an adaptive decision waits for the pass before it.
SCHEDULE = ("stream", items_in_flight)


#: The render settings that a RenderOptions field of the same name overrides (the ``render``
#: command's options, backend/render_settings.py ``cli``; --strict is handled by the loader).
OPTION_SETTINGS = ("spp", "seed", "time_limit", "noise_target", "min_spp", "max_bounces", "sampler")


@dataclass
class RenderOptions:
    spp: int | None = None
    seed: int | None = None
    workers: int | None = None
    time_limit: float | None = None
    noise_target: float | None = None
    min_spp: int | None = None
    max_bounces: int | None = None
    sampler: str | None = None
    resolution: tuple[int, int] | None = None
    parallel: str | None = None          # "threads" | "processes" | None (the scene's choice)
    cluster: str | None = None           # Dask scheduler address or "local:N" (backend/cluster.py)
    cluster_files: str = "send"          # "send": content-hashed copies; "shared": same paths
    cluster_timeout: float | None = None  # s to reach the scheduler (None: cluster.CONNECT_TIMEOUT)
    cluster_priority: int = 0            # higher first: frames of an animation in order
    view: str | None = None              # render the camera of this named view (scene "views")

    def apply(self, scene) -> None:
        if self.view is not None:
            select_view(scene, self.view)
        s = scene.settings
        for name in OPTION_SETTINGS:
            value = getattr(self, name)
            if value is not None:
                setattr(s, name, value)
        if self.resolution is not None:
            sx = self.resolution[0] / scene.width
            sy = self.resolution[1] / scene.height
            scene.width, scene.height = self.resolution
            if scene.crop is not None:
                x0, y0, x1, y1 = scene.crop
                scene.crop = (int(x0 * sx), int(y0 * sy), max(int(x1 * sx), int(x0 * sx) + 1),
                              max(int(y1 * sy), int(y0 * sy) + 1))


def select_view(scene, view: str) -> None:
    """Render through the camera of a named view (the scene's ``views``: stereo eyes, multi-view
    cameras); LaminaError if the scene has no such view."""
    if view not in scene.views:
        known = ", ".join(sorted(scene.views)[:12]) or "none"
        raise LaminaError(f"--view {view[:60]!r}: the scene has no such view (its views: {known})")
    scene.camera = scene.views[view]


@dataclass
class RenderResult:
    film: FilmAccumulator
    spp_done: int
    elapsed: float
    cpu_time: float
    interrupted: bool
    stats: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    error: str | None = None       # why the render stopped early (the film holds what was merged)


class _SerialItems:
    """Items rendered one after the other in this thread."""

    def run(self, items, should_stop, window: int = 1):
        for item in items:
            try:
                result = render_item(item)
            except Exception as exc:  # noqa: BLE001 - any failure stops the render, named
                raise Failed(failure_text(exc)) from exc
            yield result

    def close(self, stopped: bool) -> None:
        pass


class _ThreadItems:
    """Worker threads sharing this process's scene (threads cannot die alone: an exception in
    one is a failure of the render)."""

    def __init__(self, workers: int):
        self.pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="lamina-render")

    def run(self, items, should_stop, window: int):
        """Results in item order; up to ``window`` items submitted ahead of the one merged."""
        from collections import deque
        futures: deque = deque()
        source = iter(items)
        try:
            while True:
                for item in source:
                    futures.append(self.pool.submit(render_item, item))
                    if len(futures) >= window:
                        break
                if not futures:
                    return
                f = futures.popleft()
                try:
                    result = wait_for(f, should_stop)
                except (Stopped, FutureTimeout):
                    raise
                except Exception as exc:  # noqa: BLE001
                    raise Failed(failure_text(exc)) from exc
                yield result
        finally:
            for f in futures:
                f.cancel()

    def close(self, stopped: bool) -> None:
        # Threads cannot be killed: wait for the items they are on (each is short).
        self.pool.shutdown(wait=True, cancel_futures=True)


class _Worker:
    """One worker process and the pipe to it; ``item`` is the index it is rendering."""

    def __init__(self, ctx, source, options, prepared: bool):
        self.conn, child = ctx.Pipe(duplex=True)
        self.proc = ctx.Process(target=_worker_main, args=(child, source, options, prepared),
                                daemon=True, name="lamina-worker")
        if prepared:                # forked: buffered output would be written twice
            import sys
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.flush()
                except (OSError, ValueError, AttributeError):
                    pass
        self.proc.start()
        child.close()           # so that the worker's death reads as end-of-file here
        self.item = None

    def stop(self, kill: bool) -> None:
        try:
            if kill:
                self.proc.kill()
            else:
                self.conn.send(None)
        except (OSError, ValueError):
            pass
        self.proc.join(timeout=None if kill else 10)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(timeout=5)
        self.conn.close()


def _worker_main(conn, source, options, prepared: bool = False) -> None:
    """A worker process: load the scene (unless ``prepared``: forked from a master that holds
    it), then render the items it is sent until told to stop (None) or the master is gone (end
    of file)."""
    # Ctrl-C goes to the whole process group; the master decides how to stop. SIGTERM ends a
    # worker (a forked one would otherwise inherit the master's handler and ignore it).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    setup_error = None
    if not prepared:
        try:
            setup_local(source, options)
        except Exception as exc:  # noqa: BLE001 - reported with the first item
            setup_error = failure_text(exc)
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        index, item = message
        if setup_error is not None:
            reply = ("error", index, setup_error)
        else:
            try:
                reply = ("ok", index, render_item(item))
            except Exception as exc:  # noqa: BLE001 - any failure stops the render, named
                reply = ("error", index, failure_text(exc))
        try:
            conn.send(reply)
        except (OSError, ValueError):
            return


class _ProcessItems:
    """Worker processes, one item at a time each, over one pipe per worker. A worker that dies
    (its pipe ends, its process sentinel fires) is replaced by a new one and its item goes back
    to the queue, to whichever worker is free first (module docstring). No pool manager thread:
    nothing can hang on a half-written result.

    On Linux the workers are *forked* from this process after it has loaded the scene and built
    the BVH, so they share both (copy-on-write pages that nobody writes: scene arrays, textures,
    embree's BVH): a render's peak memory grows by a worker's working set, not by a scene copy,
    per extra worker (benchmarks/worker_memory.py), and a lost worker is replaced in
    milliseconds. The child never builds a BVH or calls into embree's task system, which is what
    makes forking a process with embree's threads safe; it only traces. Elsewhere (no fork on
    Windows, an unsafe one on macOS), or with ``LAMINA_WORKER_START=spawn``, workers are spawned
    and each loads the scene itself."""

    def __init__(self, workers: int, source, options, warn, scene=None):
        self.fork = scene is not None and _fork_workers()
        if self.fork:
            import multiprocessing
            self.ctx = multiprocessing.get_context("fork")
            setup_local(source, options, scene)
            # embree builds the BVH on the first query: build it here, once, before forking.
            WORKER["accel"].commit()
        else:
            self.ctx = _spawn_context()
        self.source, self.options, self.warn = source, options, warn
        self.losses = 0
        self.workers = [self._new() for _ in range(workers)]

    def _new(self) -> _Worker:
        return _Worker(self.ctx, self.source, self.options, self.fork)

    def run(self, items, should_stop, window: int):
        """Results in item order; items are taken from ``items`` as workers become free, at most
        ``window`` ahead of the one merged."""
        from collections import deque
        from multiprocessing.connection import wait
        source = iter(items)
        items = {}                      # index -> item, from taken until merged
        taken = 0
        exhausted = False
        queue: deque = deque()
        results: dict = {}
        next_out = 0
        while True:
            while not exhausted and taken - next_out < window:
                try:
                    items[taken] = next(source)
                except StopIteration:
                    exhausted = True
                    break
                queue.append(taken)
                taken += 1
            if exhausted and next_out == taken:
                return
            if next_out in results:
                items.pop(next_out, None)
                yield results.pop(next_out)
                next_out += 1
                continue
            if should_stop():
                raise Stopped
            for w in self.workers:
                if w.item is None and queue:
                    w.item = queue.popleft()
                    try:
                        w.conn.send((w.item, items[w.item]))
                    except (OSError, ValueError):
                        pass                       # dead: its sentinel says so below
            busy = [w for w in self.workers if w.item is not None]
            ready = set(wait([w.conn for w in busy] + [w.proc.sentinel for w in busy], timeout=0.2))
            for k, w in enumerate(self.workers):
                if w.item is None or not ({w.conn, w.proc.sentinel} & ready):
                    continue
                reply = None
                if w.conn in ready or w.conn.poll():
                    try:
                        reply = w.conn.recv()
                    except (EOFError, OSError):
                        reply = None               # died, possibly halfway through a reply
                if reply is None:
                    queue.appendleft(w.item)
                    self.workers[k] = self._replace(w, should_stop)
                    continue
                kind, index, payload = reply
                w.item = None
                if kind != "ok":
                    raise Failed(payload)
                results[index] = payload

    def _replace(self, w: _Worker, should_stop) -> _Worker:
        """A new worker for one that died (its item is already back in the queue)."""
        w.proc.join(timeout=2)
        code = w.proc.exitcode
        w.stop(kill=True)
        # SIGTERM to the whole process group reaches this process too: give its handler a
        # moment; a stop request wins over redoing the work.
        for _ in range(5):
            if should_stop():
                raise Stopped
            time.sleep(0.05)
        self.losses += 1
        how = _describe_exit(code)
        if self.losses > MAX_WORKER_LOSSES:
            raise Failed(f"worker processes were lost {self.losses} times (last: {how}); the render "
                          f"stopped after {MAX_WORKER_LOSSES} recoveries. Too little memory? Try "
                          f"fewer --workers")
        self.warn(f"a worker process was lost ({how}); its work item is redone by a new worker: "
                  f"the image is unaffected (loss {self.losses} of at most {MAX_WORKER_LOSSES})")
        return self._new()

    def close(self, stopped: bool) -> None:
        for w in self.workers:
            w.stop(kill=stopped)


def _fork_workers() -> bool:
    import multiprocessing
    import sys
    return (sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()
            and os.environ.get("LAMINA_WORKER_START", "fork") != "spawn")


def _describe_exit(code) -> str:
    """How a worker process ended, from its exit code."""
    if code is not None and code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        hint = ", e.g. by the out-of-memory killer" if -code == getattr(signal, "SIGKILL", None) else ""
        return f"killed by {name}{hint}"
    if code:
        return f"exited with status {code}"
    return "its connection closed"


# --------------------------------------------------------------------------- master side

def plan_round(active: np.ndarray, spp_block: int, round_index: int, seed: int, sample0: int = 0) -> list:
    """Split the active pixels into bands of about LANES_PER_ITEM lanes; every pixel of the round
    takes samples sample0 … sample0 + spp_block − 1."""
    per_band = max(1, LANES_PER_ITEM // spp_block)
    n_bands = max(math.ceil(active.size / per_band), min(MIN_ITEMS_PER_ROUND, active.size))
    bands = np.array_split(active, n_bands)
    return [((round_index, b), band, spp_block, seed, sample0) for b, band in enumerate(bands) if band.size]


def choose_spp_block(pixel_count: int, spp: int) -> int:
    """Samples per item per pixel: fill LANES_PER_ITEM for small images, 1 for large ones."""
    block = max(1, LANES_PER_ITEM * MIN_ITEMS_PER_ROUND // max(pixel_count, 1))
    return int(min(block, spp))


def relative_error(film: FilmAccumulator, pixels: np.ndarray) -> np.ndarray:
    n = film.count[pixels].astype(np.float64)
    mean = film.sum[pixels] / np.maximum(n, 1)[:, None]
    var = np.maximum(film.sum_sq[pixels] / np.maximum(n, 1)[:, None] - mean * mean, 0.0)
    var_mean = var * (n / np.maximum(n - 1, 1) / np.maximum(n, 1))[:, None]
    lum = np.abs(mean @ LUMINANCE)
    # Absolute floor so near-black pixels converge (relative error is meaningless there).
    return np.sqrt(var_mean @ (LUMINANCE ** 2)) / np.maximum(lum, 1e-3)


class Renderer:
    """Runs a render; calls ``on_progress(event_dict)`` as items complete."""

    def __init__(self, scene, source, options: RenderOptions | None = None, on_progress=None,
                 partial_callback=None, partial_interval: float = 2.0):
        self.scene = scene
        self.source = source
        self.options = options or RenderOptions()
        self.on_progress = on_progress or (lambda event: None)
        self.partial_callback = partial_callback
        self.partial_interval = partial_interval
        self._stop = False
        self._warnings: list[str] = []

    def request_stop(self, *_):
        self._stop = True

    def run(self) -> RenderResult:
        scene = self.scene
        s = scene.settings
        W, H = scene.width, scene.height
        x0, y0, x1, y1 = scene.crop or (0, 0, W, H)
        ys, xs = np.mgrid[y0:y1, x0:x1]
        all_pixels = (ys * W + xs).ravel().astype(np.int64)
        film = FilmAccumulator(W, H, getattr(scene, "passes", None))
        film.transparent = scene.transparent
        spp = s.spp
        block = choose_spp_block(all_pixels.size, spp)
        rounds = math.ceil(spp / block)
        workers = self.options.workers or os.cpu_count() or 1
        workers = max(1, min(workers, MAX_WORKERS))
        totals: dict = {}
        t_start = time.perf_counter()
        cpu_start = time.process_time()
        last_partial = t_start
        active = all_pixels
        done_samples = 0            # lane-samples merged
        planned_samples = all_pixels.size * spp
        spp_done = 0
        interrupted = False
        error = None
        if self.options.cluster:
            # The workers compile (or load) the kernels; this process only merges.
            from .cluster import CONNECT_TIMEOUT, ClusterItems
            runner = ClusterItems(self.options.cluster, scene, self.source, self.options, self._warn,
                                  shared_files=self.options.cluster_files == "shared",
                                  timeout=self.options.cluster_timeout or CONNECT_TIMEOUT)
            workers, parallel = runner.workers, "cluster"
        else:
            from .warmup import ensure_compiled
            ensure_compiled(self.on_progress)
            from .layered.tabulated import prepare as prepare_tables
            prepare_tables(scene.materials, self.on_progress)
            parallel = self.options.parallel or default_parallel(scene)
            if workers > 1 and parallel == "processes":
                runner = _ProcessItems(workers, self.source, self.options, self._warn, scene)
            else:
                setup_local(self.source, self.options, scene)
                runner = _ThreadItems(workers) if workers > 1 else _SerialItems()
        start = {"event": "start", "width": W, "height": H, "spp": spp, "workers": workers,
                 "parallel": parallel}
        if self.options.cluster:
            start["cluster"] = self.options.cluster
            start.update(runner.stats)
        self.on_progress(start)
        window = items_in_flight(workers)
        try:
            r = 0
            while r < rounds:
                if self._stop:                     # a stop request between two passes
                    interrupted = True
                    break
                if active.size == 0:
                    break
                if r > 0 and s.time_limit and time.perf_counter() - t_start > s.time_limit:
                    break                          # the limit passed during the first pass
                # Passes that need no adaptive decision between them go out as one stream of
                # items: all of them without a noise target, else up to the first pass after which
                # a pixel can have min_spp samples, then one pass at a time (each decision needs
                # the pass before it merged).
                last = r + 1
                if s.noise_target <= 0:
                    last = rounds
                else:
                    while last < rounds and min(last * block, spp) < s.min_spp:
                        last += 1
                group_active = active
                issued: dict = {}

                def stream(first=r, end=last, pixels=group_active, issued=issued):
                    for p in range(first, end):
                        for item in plan_round(pixels, min(block, spp - p * block), p, s.seed, p * block):
                            issued[item[0]] = item
                            yield item

                pass_pixels = group_active.size
                pass_done = 0                      # pixels of the current pass merged
                for key, result, info in runner.run(stream(), lambda: self._stop, window):
                    _, band, this_block, _, _ = issued.pop(tuple(key))
                    p = key[0]
                    # The time limit never cuts the first pass short: every pixel gets its first
                    # samples (a limit shorter than one pass would leave black bands); after it, an
                    # item that finishes past the limit is not merged.
                    if p > 0 and s.time_limit and time.perf_counter() - t_start > s.time_limit:
                        self._stop = True          # not an interruption: the render is complete
                        break
                    dropped = film.add(band, result)
                    if dropped:
                        info["samples_nonfinite_dropped"] = info.get("samples_nonfinite_dropped", 0) + dropped
                    stats.merge(totals, info)
                    done_samples += band.size * this_block
                    pass_done += band.size
                    now = time.perf_counter()
                    elapsed = now - t_start
                    rate = done_samples / max(elapsed, 1e-9)
                    if pass_done == pass_pixels:   # pass p complete
                        spp_done += this_block
                        pass_done = 0
                        samples = spp_done
                    else:
                        # samples per pixel so far, counting the part of this pass that is done
                        samples = round(spp_done + this_block * pass_done / max(pass_pixels, 1), 2)
                    self.on_progress({"event": "progress", "done": spp_done, "round": p, "samples": samples,
                                      "total": spp, "fraction": round(min(done_samples / max(planned_samples, 1), 1.0), 4),
                                      "elapsed": round(elapsed, 3),
                                      "eta": round((planned_samples - done_samples) / max(rate, 1e-9), 2),
                                      "samples_per_second": round(rate, 1)})
                    if self.partial_callback and now - last_partial >= self.partial_interval:
                        self.partial_callback(film, spp_done)
                        last_partial = now
                    if self._stop:
                        interrupted = True
                        break
                else:
                    r = last
                    if s.noise_target > 0:
                        ready = film.count[active] >= s.min_spp
                        if ready.any():
                            err = relative_error(film, active)
                            converged = ready & (err < s.noise_target)
                            # Samples not taken any more leave the plan (for progress and ETA).
                            planned_samples -= int(converged.sum()) * (spp - spp_done)
                            active = active[~converged]
                    continue
                break
        except (Stopped, KeyboardInterrupt):
            interrupted = True
        except Failed as exc:
            error = str(exc)
        finally:
            runner.close(stopped=self._stop or interrupted or error is not None)
        elapsed = time.perf_counter() - t_start
        totals["master_cpu_time"] = time.process_time() - cpu_start
        totals.update(getattr(runner, "stats", {}))
        return RenderResult(film, spp_done, elapsed, totals.get("cpu_time", 0.0), interrupted, totals,
                            list(scene.warnings) + self._warnings, error)

    def _warn(self, message: str) -> None:
        self._warnings.append(message)
        self.on_progress({"event": "warning", "message": message})


def default_parallel(scene) -> str:
    """Threads share everything and scale: all per-lane work is compiled and releases the GIL,
    the layered BSDF included (measured on a layered scene: threads 2.6–3.3× faster in wall time
    than processes, which each load the scene and the kernels)."""
    return "threads"


def _spawn_context():
    import multiprocessing
    return multiprocessing.get_context("spawn")


def install_signal_handlers(renderer: Renderer) -> None:
    """SIGINT/SIGTERM stop the render cleanly; what is done is still written."""
    signal.signal(signal.SIGINT, renderer.request_stop)
    try:
        signal.signal(signal.SIGTERM, renderer.request_stop)
    except (ValueError, OSError):  # not in the main thread / unsupported
        pass
