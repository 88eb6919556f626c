"""How one render scales with workers: recorded here, simulated for 1…64 workers, measured where
the cores exist (issue 37, "every core, every machine").

    .venv/bin/python -m benchmarks.parallel_scaling [--cases demo,cornell,showcase,showcase1080]
        [--workers 1,2,4,8,16,32,64] [--real auto|off|1,2,...] [--runnable 16]

1. **Record.** Each case is rendered once in this process on one worker (the serial runner: the
   main thread renders the items itself). Timers wrap the compiled entry points that release the
   GIL (camera rays, shading, embree's closest-hit and occlusion loops, the shadow-ray sum, the
   film's accumulation), so for every work item we know its thread CPU time, the part of it spent
   without the GIL, and how many such calls it made; the rest of the item's time holds the GIL.
   The main thread's CPU outside items is the master's serial work (planning, merging, progress).
2. **Simulate.** A discrete-event model of the render's schedule on P worker threads: each item is
   its GIL-held time cut into equal pieces between its GIL-free calls; one GIL (first come, first
   served); the master merges items in item order (its work holds the GIL, except the film's
   compiled accumulation). The schedule is the one the code under test declares
   (``backend.render.SCHEDULE``: ``("stream", window)`` keeps ``window(P)`` items in flight;
   without it, the previous code's rounds: every item of a round before the next round starts).
   Predicted speed-up = simulated time on 1 worker / on P workers.
3. **Real renders** (``--real``): whole renders in this process at 1…N threads (N = the machine's
   cores by default, and at least 2), interleaved 1, N, N, 1, …, render-only wall seconds.
4. **Peak memory** (``--memory 1,16,64``): the peak resident memory of whole CLI renders with
   that many worker threads (each thread keeps its scratch; ``items_in_flight`` results wait).
5. **Runnable threads** (``--runnable 16``): a CLI render with that many worker threads, sampling
   the state of every thread of the process (``/proc/PID/task/*/stat``) every 10 ms between the
   render's start and end events; prints the mean number in state R (running or runnable).

Calibration against the 16-core figures measured in issue 37 (the code before the change): copy
this file into a checkout of that code (``git worktree add /tmp/old 60590b4``) and run it there
(docs/benchmarks.md, "Parallel scaling").
"""
from __future__ import annotations

import argparse
import heapq
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

#: name: (scene file or builder, spp, resolution or None)
CASES = {
    "demo": ("demo/demo.json", 64, None),
    "cornell": ("cornell", 128, None),
    "showcase": ("showcase/showcase.json", 32, None),
    "showcase1080": ("showcase/showcase.json", 16, (1920, 1080)),
}

#: Measured on a 16-core machine (issue 37): render-only speed-up of 16 threads over one.
MEASURED_16 = {"demo": 2.25, "cornell": 2.84}

# The compiled calls that run without the GIL, as (module, attribute).
NOGIL_CALLS = (("backend.kernels.integrator", "shade"), ("backend.kernels.integrator", "add_unoccluded"),
               ("backend.integrator", "camera_rays"), ("backend.kernels.trace", "intersect_rays"),
               ("backend.kernels.trace", "occluded_rays"), ("backend.kernels.film", "accumulate"),
               ("backend.integrator", "run_item"), ("backend.integrator", "start_lanes"))


@dataclass
class Item:
    key: tuple
    cpu: float          # thread CPU seconds of the item
    nogil: float        # of which inside compiled calls that release the GIL
    calls: int          # how many such calls


@dataclass
class Recording:
    case: str
    items: list = field(default_factory=list)
    setup: float = 0.0           # master's CPU before the first item (tracer, BVH): serial
    master_gil: float = 0.0      # master's serial CPU holding the GIL, after the setup
    master_nogil: float = 0.0    # master's compiled merge (film accumulation)
    wall: float = 0.0
    schedule: tuple = ("rounds", None)

    @property
    def item_cpu(self) -> float:
        return sum(i.cpu for i in self.items)

    @property
    def gil_held(self) -> float:
        return sum(i.cpu - i.nogil for i in self.items) + self.master_gil + self.setup


# --------------------------------------------------------------------------- recording

class _Timers:
    """Thread-local accumulators around the GIL-free calls."""

    def __init__(self):
        self.local = threading.local()
        self.saved = []

    def wrap(self, fn):
        local = self.local

        def timed(*args, **kwargs):
            t0 = time.thread_time()
            try:
                return fn(*args, **kwargs)
            finally:
                local.nogil = getattr(local, "nogil", 0.0) + time.thread_time() - t0
                local.calls = getattr(local, "calls", 0) + 1
        return timed

    def install(self):
        import importlib
        for module, name in NOGIL_CALLS:
            try:
                mod = importlib.import_module(module)
            except ImportError:
                continue
            fn = getattr(mod, name, None)
            if fn is None:
                continue
            self.saved.append((mod, name, fn))
            setattr(mod, name, self.wrap(fn))

    def remove(self):
        for mod, name, fn in self.saved:
            setattr(mod, name, fn)
        self.saved.clear()

    def take(self):
        out = (getattr(self.local, "nogil", 0.0), getattr(self.local, "calls", 0))
        self.local.nogil, self.local.calls = 0.0, 0
        return out


def scene_path(case: str, work: Path) -> Path:
    source = CASES[case][0]
    if source == "cornell":                 # the peer benchmark's Cornell box
        from .peers.scenes import cornell
        path = work / "cornell.json"
        path.write_text(json.dumps(cornell(256)))
        return path
    return REPO / source


def _load(case: str, work: Path, workers: int, path: Path | None = None, spp=None, resolution=None):
    from backend.render import RenderOptions
    from backend.scene.loader import load_scene
    if path is None:
        _, spp, resolution = CASES[case]
        path = scene_path(case, work)
    scene = load_scene(path)
    options = RenderOptions(spp=spp, resolution=resolution, workers=workers, parallel="threads")
    options.apply(scene)
    return scene, path, options


def record(case: str, work: Path, path: Path | None = None, spp=None, resolution=None) -> Recording:
    """Render ``case`` (or the scene at ``path``) on one worker, timing every item and the master
    (see the module docstring)."""
    import backend.render as render
    from backend.render import Renderer
    scene, path, options = _load(case, work, 1, path, spp, resolution)
    rec = Recording(case, schedule=getattr(render, "SCHEDULE", ("rounds", None)))
    timers = _Timers()
    original = render.render_item
    merge_nogil = [0.0]

    def timed_item(item, *args):
        if not rec.items:
            rec.setup = time.thread_time() - c0
        merge_nogil[0] += timers.take()[0]       # the film's accumulation since the last item
        t0 = time.thread_time()
        out = original(item, *args)
        cpu = time.thread_time() - t0
        nogil, calls = timers.take()
        rec.items.append(Item(tuple(item[0]), cpu, nogil, calls))
        return out

    from backend.layered.tabulated import prepare as prepare_tables
    from backend.warmup import ensure_compiled
    ensure_compiled(lambda e: None)
    prepare_tables(scene.materials, lambda e: None)   # a cold table cache is not the schedule's
    timers.install()
    render.render_item = timed_item
    c0 = time.thread_time()
    try:
        renderer = Renderer(scene, str(path), options)
        t0, c0 = time.perf_counter(), time.thread_time()
        result = renderer.run()
        rec.wall = time.perf_counter() - t0
        main_cpu = time.thread_time() - c0
        merge_nogil[0] += timers.take()[0]      # the film's accumulation, on this thread
    finally:
        render.render_item = original
        timers.remove()
    if result.error:
        raise SystemExit(f"{case}: {result.error}")
    master = max(main_cpu - rec.item_cpu - rec.setup, 0.0)
    rec.master_nogil = min(merge_nogil[0], master)
    rec.master_gil = master - rec.master_nogil
    return rec


# --------------------------------------------------------------------------- simulation

def _window(schedule, workers: int) -> int | None:
    kind, window = schedule
    if kind != "stream":
        return None
    return int(window(workers)) if callable(window) else int(window)


def simulate(rec: Recording, workers: int, task_overhead: float = 0.0) -> float:
    """Simulated wall seconds of the recorded render on ``workers`` threads (module docstring).
    ``task_overhead``: seconds of serial work per item on the master's side (a Dask scheduler's
    per-task cost: benchmarks/cluster_overhead.py), counted as if it held the GIL."""
    items = rec.items
    n = len(items)
    if n == 0:
        return 0.0
    per_merge_gil = rec.master_gil / n + task_overhead
    per_merge_nogil = rec.master_nogil / n
    window = _window(rec.schedule, workers)
    rounds = [it.key[0] if rec.schedule[0] == "rounds" else 0 for it in items]

    def pieces(it: Item):
        g = max(it.cpu - it.nogil, 0.0)
        k = max(it.calls, 0)
        f = it.nogil / k if k else 0.0
        out = [(True, g / (k + 1))]
        for _ in range(k):
            out += [(False, f), (True, g / (k + 1))]
        return out

    # Threads 0..workers-1 render, thread `workers` is the master.
    master = workers
    plan = {}                       # thread -> list of (needs_gil, seconds), current position
    events = []                     # (time, seq, thread)
    seq = 0
    gil_free = True
    gil_waiters = []
    queue = []                      # item indices submitted, not yet started
    done = [False] * n
    merged = 0
    submitted = 0
    idle = list(range(workers))
    master_busy = False
    now = 0.0
    item_of = {}

    def start_segment(th, t):
        nonlocal seq, gil_free
        segs, pos = plan[th]
        if pos == len(segs):
            finish(th, t)
            return
        gil, dur = segs[pos]
        if gil:
            if gil_free:
                gil_free = False
                heapq.heappush(events, (t + dur, seq, th)); seq += 1
            else:
                gil_waiters.append(th)
        else:
            heapq.heappush(events, (t + dur, seq, th)); seq += 1

    def end_segment(th, t):
        nonlocal gil_free
        segs, pos = plan[th]
        if segs[pos][0]:
            if gil_waiters:
                nxt = gil_waiters.pop(0)
                gil, dur = plan[nxt][0][plan[nxt][1]]
                heapq.heappush(events, (t + dur, seq_next(), nxt))
            else:
                gil_free = True
        plan[th] = (segs, pos + 1)
        start_segment(th, t)

    def seq_next():
        nonlocal seq
        seq += 1
        return seq

    def submit_more(t):
        nonlocal submitted
        if window is None:          # rounds: the next round once every item before it is merged
            if merged == submitted and submitted < n:
                r = rounds[submitted]
                while submitted < n and rounds[submitted] == r:
                    queue.append(submitted); submitted += 1
        else:
            while submitted < n and submitted - merged < window:
                queue.append(submitted); submitted += 1
        dispatch(t)

    def dispatch(t):
        while idle and queue:
            th = idle.pop(0)
            i = queue.pop(0)
            item_of[th] = i
            plan[th] = (pieces(items[i]), 0)
            start_segment(th, t)

    def try_merge(t):
        nonlocal master_busy
        if not master_busy and merged < n and done[merged]:
            master_busy = True
            plan[master] = ([(True, per_merge_gil), (False, per_merge_nogil)], 0)
            start_segment(master, t)

    def finish(th, t):
        nonlocal merged, master_busy
        if th == master:
            merged += 1
            master_busy = False
            submit_more(t)
            try_merge(t)
            return
        done[item_of.pop(th)] = True
        idle.append(th)
        dispatch(t)
        try_merge(t)

    submit_more(rec.setup)
    while events:
        now, _, th = heapq.heappop(events)
        end_segment(th, now)
    return now


def predict(rec: Recording, workers_list, task_overhead: float = 0.0) -> dict:
    """Speed-up on P workers over one local worker (no task overhead)."""
    one = simulate(rec, 1)
    return {p: one / max(simulate(rec, p, task_overhead), 1e-12) for p in workers_list}


# --------------------------------------------------------------------------- real renders

def real_render(case: str, work: Path, workers: int) -> float:
    from backend.render import Renderer
    scene, path, options = _load(case, work, workers)
    result = Renderer(scene, str(path), options).run()
    if result.error:
        raise SystemExit(f"{case}: {result.error}")
    return result.elapsed


def runnable_threads(case: str, work: Path, workers: int) -> dict:
    """Mean number of the render process's threads in state R, sampled every 10 ms between its
    start and done events (``--progress json``)."""
    _, spp, resolution = CASES[case]
    cmd = [sys.executable, "-m", "backend", "render", str(scene_path(case, work)), "-o",
           str(work / "runnable.exr"), "--spp", str(spp), "--workers", str(workers), "--progress", "json"]
    if resolution:
        cmd += ["--resolution", f"{resolution[0]}x{resolution[1]}"]
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    state = {"on": False, "end": False}

    def read():
        for line in proc.stdout:
            if '"event": "start"' in line or '"event":"start"' in line:
                state["on"] = True
            elif '"event": "done"' in line or '"event":"done"' in line:
                state["end"] = True
        state["end"] = True
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    samples = []
    threads = []
    task_dir = Path(f"/proc/{proc.pid}/task")
    while not state["end"] and proc.poll() is None:
        if state["on"]:
            r = total = 0
            try:
                for task in task_dir.iterdir():
                    try:
                        stat = (task / "stat").read_text()
                    except OSError:
                        continue
                    total += 1
                    r += stat[stat.rindex(")") + 2] == "R"
            except OSError:
                break
            samples.append(r)
            threads.append(total)
        time.sleep(0.01)
    proc.wait()
    reader.join(timeout=5)
    return {"samples": len(samples), "mean_runnable": statistics.fmean(samples) if samples else 0.0,
            "threads": max(threads) if threads else 0}


def peak_memory(case: str, work: Path, workers: int) -> float:
    """Peak resident memory (MiB) of a whole CLI render with that many worker threads."""
    _, spp, resolution = CASES[case]
    cmd = [sys.executable, "-m", "backend", "render", str(scene_path(case, work)), "-o",
           str(work / "memory.exr"), "--spp", str(spp), "--workers", str(workers), "--progress", "none"]
    if resolution:
        cmd += ["--resolution", f"{resolution[0]}x{resolution[1]}"]
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"{case}: render with {workers} workers failed ({proc.returncode})")
    return usage.ru_maxrss / 1024.0


# --------------------------------------------------------------------------- main

def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="demo,cornell,showcase,showcase1080")
    ap.add_argument("--workers", default="1,2,4,8,16,32,64")
    ap.add_argument("--real", default="auto", help="auto (1 and every power of 2 up to the cores, at "
                    "least 2), off, or a list of thread counts")
    ap.add_argument("--repeat", type=int, default=2, help="interleaved pairs of real renders")
    ap.add_argument("--runnable", type=int, default=0, help="worker threads of the runnable-thread check (0: off)")
    ap.add_argument("--memory", default="", help="worker-thread counts whose peak memory to measure, e.g. 1,16,64")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures here")
    args = ap.parse_args(argv)
    import backend
    workers_list = [int(w) for w in args.workers.split(",")]
    cores = os.cpu_count() or 1
    work = Path(tempfile.mkdtemp(prefix="lamina-scaling-"))
    print(f"backend: {Path(backend.__file__).parent}; {cores} cores; load {os.getloadavg()[0]:.2f}")
    report = {}
    for case in args.cases.split(","):
        rec = record(case, work)
        pred = predict(rec, workers_list)
        cpus = [i.cpu for i in rec.items]
        gil_share = rec.gil_held / max(rec.item_cpu + rec.master_gil + rec.master_nogil + rec.setup, 1e-12)
        print(f"\n{case}: {len(rec.items)} items, item CPU {rec.item_cpu:.2f} s (per item {min(cpus) * 1e3:.1f}"
              f"–{max(cpus) * 1e3:.1f} ms), set-up {rec.setup:.3f} s, merging {rec.master_gil + rec.master_nogil:.3f} s "
              f"(GIL {rec.master_gil:.3f}), GIL held {rec.gil_held:.3f} s = {100 * gil_share:.2f} % "
              f"of the CPU; schedule {rec.schedule[0]}")
        print("  predicted speed-up: " + "  ".join(f"{p}: {s:.2f}×" for p, s in pred.items()))
        if case in MEASURED_16 and 16 in pred:
            m = MEASURED_16[case]
            if rec.schedule[0] == "rounds":       # the code the 16-core figures were measured on
                print(f"  calibration: measured at 16 threads {m:.2f}×, predicted/measured {pred[16] / m:.2f}")
            else:
                print(f"  (the previous code, rounds with a barrier: {m:.2f}× measured at 16 threads)")
        entry = {"items": len(rec.items), "item_cpu": rec.item_cpu, "setup": rec.setup, "master_gil": rec.master_gil,
                 "master_nogil": rec.master_nogil, "gil_held": rec.gil_held,
                 "predicted": {str(p): round(s, 3) for p, s in pred.items()}}
        counts = [] if args.real == "off" else (
            sorted({1, *[2 ** k for k in range(1, 7) if 2 ** k <= max(cores, 2)]}) if args.real == "auto"
            else [int(w) for w in args.real.split(",")])
        if len(counts) > 1:
            real_render(case, work, 1)                          # warm the caches
            times = {w: [] for w in counts}
            for r in range(args.repeat):
                for w in (counts if r % 2 == 0 else counts[::-1]):
                    times[w].append(real_render(case, work, w))
            base = statistics.median(times[1])
            print("  real (render wall s, median): " + "  ".join(
                f"{w}: {statistics.median(t):.2f} s ({base / statistics.median(t):.2f}×)" for w, t in times.items()))
            entry["real"] = {str(w): t for w, t in times.items()}
        if args.runnable:
            run = runnable_threads(case, work, args.runnable)
            print(f"  --workers {args.runnable}: mean runnable threads {run['mean_runnable']:.1f} of "
                  f"{run['threads']} ({run['samples']} samples every 10 ms)")
            entry["runnable"] = run
        if args.memory:
            peaks = {int(w): peak_memory(case, work, int(w)) for w in args.memory.split(",")}
            print("  peak memory: " + "  ".join(f"{w} threads {m:.0f} MiB" for w, m in peaks.items()))
            entry["peak_mib"] = peaks
        report[case] = entry
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
