"""Work items on a Dask cluster (``render --cluster ADDRESS``), docs/cluster.md.

One more runner next to the serial, thread and process runners of render.py, with the same
``run(items, should_stop)`` / ``close(stopped)`` interface: every work item becomes one Dask task
that calls the same item function (``work_items.render_item``) on a worker, and ``run`` yields the
results in item order. Items are pure functions of their key, so the merged image is
bit-identical to a local render whatever the number of workers — and whether a task ran once or
was rerun after its worker was lost (Dask reschedules the tasks of a lost worker; a result is
only ever merged once, from the future of its item).

The scene reaches the workers as content-hashed files (cluster_files.py): before the first item
the master asks every worker which files it lacks and sends each missing file once per worker
cache folder. A worker loads the scene once and keeps it for the following items (and the
following render of the same scene); a worker that joins later and lacks files says so with
:class:`MissingSceneFiles`, is sent them, and the item is resubmitted.

``distributed`` is an optional dependency: importing this module does not need it, using it does
(one clear error otherwise).
"""
from __future__ import annotations

import dataclasses
import logging
import sys
import threading
import time
import uuid

from .errors import LaminaError
from .limits import MAX_WORKERS
from .work_items import Failed, Stopped, failure_text, render_item, setup_local, wait_for

DISTRIBUTED_PIN = "distributed==2026.8.0"        # the version tested (requirements-dev.txt)
CONNECT_TIMEOUT = 10.0        # s: reaching the scheduler, and waiting for its first worker
WORKER_CHECK = 1.0            # s between looks at the worker list (to report lost workers)
MAX_RESENDS = 3               # a worker asking again and again for files it was sent: give up
PRIORITY_SPAN = 1 << 24       # more than the items of one round (65536² pixels, ≥ 65536 per item)


class MissingSceneFiles(Exception):
    """Raised by a worker's task when its cache lacks files of the scene (it joined after the
    files were sent, or its cache was deleted): the master sends them and resubmits."""

    def __init__(self, address: str, missing: list):
        super().__init__(address, missing)
        self.address, self.missing = address, missing


def parse_address(text: str) -> str:
    """``local:N`` or a scheduler address (``tcp://host:port``, ``host:port``); LaminaError otherwise."""
    text = text.strip()
    if text.startswith("local:"):
        count = text[6:]
        if not count.isdigit() or not 1 <= int(count) <= MAX_WORKERS:
            raise LaminaError(f"--cluster {text!r}: expected local:N with N from 1 to {MAX_WORKERS} "
                              f"worker processes")
        return f"local:{int(count)}"
    if "://" in text or (":" in text and text.rsplit(":", 1)[1].isdigit()):
        return text
    raise LaminaError(f"--cluster {text!r}: expected a scheduler address such as tcp://HOST:8786, "
                      f"or local:N for a local cluster of N worker processes")


def require_distributed():
    try:
        import distributed
    except ImportError:
        raise LaminaError(f"--cluster needs Dask's 'distributed' package, which is not installed "
                          f"for {sys.executable}: install it with `python -m pip install "
                          f"{DISTRIBUTED_PIN}` (docs/cluster.md)") from None
    return distributed


def connect(address: str, timeout: float = CONNECT_TIMEOUT):
    """(client, local cluster or None) for ``address``; one clear LaminaError when that fails."""
    distributed = require_distributed()
    # Dask's client logs every reconnection attempt with a traceback; Lamina reports what
    # matters itself, in one line (a lost scheduler, a lost worker).
    # Its configuration gives some child loggers levels of their own: quiet each of them.
    for name in ["distributed", *logging.root.manager.loggerDict]:
        if name == "distributed" or name.startswith("distributed."):
            logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    cluster = None
    # A local cluster's scheduler serves HTTP on port 8787 or, when that is taken (another
    # cluster), on any port, with a warning: it serves nothing Lamina needs.
    import warnings
    warnings.filterwarnings("ignore", message="Port 8787 is already in use", category=UserWarning)
    try:
        if address.startswith("local:"):
            cluster = distributed.LocalCluster(n_workers=int(address[6:]), threads_per_worker=1,
                                               processes=True, dashboard_address=None,
                                               silence_logs=logging.CRITICAL,
                                               preload=["backend.cluster"])
            client = distributed.Client(cluster, timeout=timeout)
        else:
            client = distributed.Client(address, timeout=timeout)
    except (OSError, TimeoutError, RuntimeError) as exc:
        if cluster is not None:
            cluster.close()
        if address.startswith("local:"):
            raise LaminaError(f"could not start a local Dask cluster ({address}): "
                              f"{type(exc).__name__}: {str(exc).strip()[:200]}") from None
        detail = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else type(exc).__name__
        raise LaminaError(f"cannot reach the Dask scheduler at {address} within {timeout:g} s "
                          f"({detail}); is `dask scheduler` running there, and the port open?") from None
    try:
        client.wait_for_workers(1, timeout=timeout)
    except (OSError, TimeoutError):
        close_connection(client, cluster)
        raise LaminaError(f"the Dask scheduler at {address} has no workers (waited {timeout:g} s); "
                          f"start some with `dask worker {address}` (docs/cluster.md)") from None
    return client, cluster


def close_connection(client, cluster) -> None:
    try:
        client.close(timeout=5)
    except Exception:  # noqa: BLE001 - closing a broken connection must not hide the real error
        pass
    if cluster is not None:
        try:
            cluster.close(timeout=10)
        except Exception:  # noqa: BLE001
            pass


# --------------------------------------------------------------------------- worker side

def dask_setup(worker) -> None:
    """Preload of the ``local:N`` cluster's worker processes (Dask calls it at their start).
    They are children of the render process, so Ctrl-C at a terminal reaches them too: they
    ignore it (each would print a traceback and die); the render process cancels their tasks
    and closes the cluster."""
    import signal
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


SCENES_KEPT = 2     # scenes a worker process keeps loaded: two frames of an animation overlap
_LOADED: dict = {}                  # key -> tracer state, oldest first
_LOAD_LOCK = threading.Lock()       # a worker process may run several tasks at once (--nthreads)


def _scene_state(package, options) -> dict:
    """The tracer for (package, options) in this worker process: loaded on the first item and
    kept for the next items and renders (the SCENES_KEPT most recently used scenes; an older
    one's memory is released)."""
    key = (package.key, repr(dataclasses.astuple(dataclasses.replace(options, cluster_priority=0))))
    with _LOAD_LOCK:
        if key in _LOADED:
            _LOADED[key] = _LOADED.pop(key)           # most recently used last
            return _LOADED[key]
        from . import cluster_files
        missing = cluster_files.missing_files(package)
        if missing:
            from distributed import get_worker
            raise MissingSceneFiles(get_worker().address, missing)
        from .warmup import ensure_compiled
        ensure_compiled()
        while len(_LOADED) >= SCENES_KEPT:
            _LOADED.pop(next(iter(_LOADED)))
        scene = cluster_files.load_package(package)
        options.apply(scene)
        state: dict = {}
        setup_local(None, options, scene, state)
        # embree builds the BVH on the first query: once here, not in racing task threads.
        import numpy as np
        state["accel"].intersect(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]))
        _LOADED[key] = state
        return state


def render_task(package, options, item) -> tuple:
    """One work item on a worker: ``work_items.render_item`` on the worker's copy of the scene."""
    return render_item(item, _scene_state(package, options))


# --------------------------------------------------------------------------- master side

class ClusterItems:
    """Runs work items as Dask tasks (module docstring). ``stats`` holds what the transfer cost."""

    def __init__(self, address: str, scene, source, options, warn, shared_files: bool = False,
                 timeout: float = CONNECT_TIMEOUT):
        from . import cluster_files
        self.address, self.options, self.warn = address, options, warn
        self.grace = timeout       # s: a lost scheduler connection may come back within this
        self.package, self.blobs = cluster_files.make_package(scene, source, shared=shared_files)
        self.client, self.cluster = connect(address, timeout)
        self.futures: list = []
        self._submitted = 0             # items submitted by this runner (their priority order)
        self.stats = {"cluster_scene_bytes_sent": 0, "cluster_scene_files_sent": 0}
        self.render_id = uuid.uuid4().hex[:12]
        try:
            self.workers = self._worker_threads()
            self._send_files(None)
        except BaseException:
            close_connection(self.client, self.cluster)
            raise
        self._known = set(self._worker_list())
        self._last_check = time.perf_counter()

    # ---- workers and files

    def _worker_list(self) -> dict:
        return self.client.scheduler_info(n_workers=-1).get("workers", {})

    def _worker_threads(self) -> int:
        return max(1, sum(int(w.get("nthreads", 1)) for w in self._worker_list().values()))

    def _send_files(self, workers) -> None:
        """Send the files the workers' caches lack, once per cache folder."""
        from . import cluster_files
        hashes = self.package.hashes()
        inventory = self.client.run(cluster_files.worker_inventory, hashes, workers=workers,
                                    on_error="return")
        mine = cluster_files.worker_inventory({})["version"]
        plan: dict = {}                # cache folder -> (a worker using it, missing hashes)
        for address, info in sorted(inventory.items()):
            if isinstance(info, BaseException):
                continue               # lost meanwhile: its tasks run elsewhere
            if info["version"] != mine:
                raise LaminaError(f"the cluster worker at {address} runs another version of Lamina's "
                                  f"backend ({info['version']}, this one is {mine}): its samples would "
                                  f"differ. Give every worker the same Lamina (docs/cluster.md)")
            if info["cache"] not in plan:
                plan[info["cache"]] = (address, set(info["missing"]))
        for address, missing in plan.values():
            for digest in sorted(missing):
                data = cluster_files.blob_bytes(self.blobs[digest])
                try:
                    self.client.run(cluster_files.store, digest, hashes[digest], data, workers=[address])
                except Exception as exc:  # noqa: BLE001 - the worker's disk, or the connection
                    what = self._file_name(digest)
                    raise LaminaError(f"could not store {what} on the cluster worker {address} "
                                      f"({type(exc).__name__}: {str(exc)[:200]}); is its cache folder "
                                      f"writable (LAMINA_CLUSTER_CACHE, docs/cluster.md)?") from None
                self.stats["cluster_scene_bytes_sent"] += len(data)
                self.stats["cluster_scene_files_sent"] += 1

    def _file_name(self, digest: str) -> str:
        if digest == self.package.document:
            return f"the scene document {self.package.where}"
        for path, (h, _) in self.package.files.items():
            if h == digest:
                return path
        return digest[:12]

    def _check_workers(self, force: bool = False) -> None:
        """Warn once per worker that left during the render (its tasks are rerun elsewhere)."""
        now = time.perf_counter()
        if now - self._last_check < WORKER_CHECK and not force:
            return
        self._last_check = now
        try:
            current = set(self._worker_list())
        except Exception:  # noqa: BLE001 - the scheduler check in _wait reports a lost connection
            return
        for address in sorted(self._known - current):
            self.warn(f"the cluster worker {address} left during the render; Dask reruns its work "
                      f"items on the other workers: the image is unaffected")
        self._known = current

    # ---- items

    def _submit(self, item, index: int):
        key, *_ = item
        # Earlier items first (merged in order); an earlier frame's items before a later one's.
        priority = self.options.cluster_priority * PRIORITY_SPAN + (PRIORITY_SPAN - 1 - min(index, PRIORITY_SPAN - 1))
        return self.client.submit(render_task, self.package, self.options, item, pure=False,
                                  key=f"lamina-{self.render_id}-{key[0]}-{key[1]}-{uuid.uuid4().hex[:6]}",
                                  priority=priority)

    def run(self, items, should_stop, window: int):
        """Results in item order, ``window`` items submitted ahead of the one merged (the
        Renderer sizes it from the cluster's worker threads)."""
        from collections import deque
        source = iter(items)
        pending: deque = deque()          # [index, item, future]: merged items leave it (and their
        taken = 0                         # results leave the workers)
        resent: dict = {}               # item index -> times its worker was sent missing files
        try:
            while True:
                for item in source:
                    future = self._submit(item, self._submitted)
                    self._submitted += 1
                    pending.append([taken, item, future])
                    taken += 1
                    if len(pending) >= window:
                        break
                if not pending:
                    break
                entry = pending[0]
                i, item = entry[0], entry[1]
                while True:
                    try:
                        result = self._wait(entry[2], should_stop)
                    except MissingSceneFiles as exc:
                        resent[i] = resent.get(i, 0) + 1
                        if resent[i] > MAX_RESENDS:
                            raise Failed(f"the cluster worker {exc.address} still lacks the scene's "
                                          f"files after they were sent {MAX_RESENDS} times (its cache "
                                          f"folder deleted during the render?)") from None
                        try:
                            self._send_files([exc.address])
                        except LaminaError as error:
                            raise Failed(str(error)) from None
                        entry[2] = self._submit(item, i)
                        continue
                    except (Stopped, Failed):
                        raise
                    except Exception as exc:  # noqa: BLE001 - any failure stops the render, named
                        raise Failed(self._failure(exc, failure_text)) from exc
                    break
                pending.popleft()
                if not pending:
                    self._check_workers(force=True)   # a loss during a short render is still told
                yield result
        finally:
            self.futures = [e[2] for e in pending]
            self._cancel()

    def _wait(self, future, should_stop):
        lost_since = None

        def check_connection():
            nonlocal lost_since
            if self.client.status != "running":
                lost_since = lost_since or time.perf_counter()
                if time.perf_counter() - lost_since > self.grace:
                    raise Failed(self._scheduler_lost())
            else:
                lost_since = None
                self._check_workers()
        return wait_for(future, should_stop, check_connection)

    def _connection_lost(self, within: float = 5.0) -> bool:
        """Whether the client has lost its scheduler, waiting up to ``within`` s (at most the
        grace period) for it to notice: a closed connection can reach a gather before the client's
        status changes (seen once in a fresh test run: "cancelled a work item (CommClosedError)"
        for a killed scheduler)."""
        end = time.perf_counter() + min(within, self.grace)
        while True:
            if self.client.status != "running":
                return True
            if time.perf_counter() >= end:
                return False
            time.sleep(0.1)

    def _scheduler_lost(self) -> str:
        return f"lost the connection to the Dask scheduler at {self.address}; the render stopped"

    def _failure(self, exc: BaseException, failure_text) -> str:
        name = type(exc).__name__
        if name == "KilledWorker":
            return (f"a work item was running on each of several cluster workers that died "
                    f"(Dask gave up on it: {str(exc)[:200]}); too little memory on the workers?")
        if name in ("CancelledError", "FutureCancelledError", "CommClosedError") or isinstance(exc, OSError):
            return self._scheduler_lost() if self._connection_lost() else (
                f"the cluster cancelled a work item ({name}: {str(exc)[:200]})")
        return failure_text(exc)

    def _cancel(self) -> None:
        pending = [f for f in self.futures if f is not None]
        self.futures = []
        if pending and self.client.status == "running":
            try:
                self.client.cancel(pending)
            except Exception:  # noqa: BLE001 - a lost scheduler has nothing left to cancel
                pass

    def close(self, stopped: bool) -> None:
        self._cancel()
        close_connection(self.client, self.cluster)
