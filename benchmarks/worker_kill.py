"""Kill one worker process at a random moment of a render; the image must not change (issue 18).

    python -m benchmarks.worker_kill [--runs 10] [--seed 0] [--resolution 240x135] [--spp 4]
                                     [--signal KILL] [--scene demo/demo.json]

Renders the scene once undisturbed with 2 worker processes (``--parallel processes``), then
``--runs`` times again, each time sending ``--signal`` to one worker process, chosen at random,
at a moment drawn uniformly from the first 90 % of the undisturbed render's working time (from
the ``start`` event to its last progress event; a kill can land while a worker is still
starting). Each run must exit 0, report the loss in exactly one warning, and write an EXR whose
every channel (combined, albedo, normal, variance, samples) is bit-identical to the undisturbed
one. Seeded: same seed ⇒ same moments and victims.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .procs import children, render_workers

ROOT = Path(__file__).resolve().parent.parent


def workers_of(pid: int) -> list[int]:
    """The render's worker processes (its children running the worker loop)."""
    return render_workers(children(pid))


def render(scene: Path, out: Path, args, kill_at: float | None = None, rng: random.Random | None = None):
    cmd = [sys.executable, "-m", "backend", "render", str(scene), "-o", str(out), "--workers", "2",
           "--parallel", "processes", "--progress", "json"]
    if args.resolution:
        cmd += ["--resolution", args.resolution]
    if args.spp:
        cmd += ["--spp", str(args.spp)]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    events, killed, t_start = [], None, None
    line = proc.stdout.readline()
    while line:
        ev = json.loads(line)
        events.append(ev)
        if ev["event"] == "start":
            t_start = time.perf_counter()
            break
        line = proc.stdout.readline()
    if kill_at is not None:
        while time.perf_counter() - t_start < kill_at and proc.poll() is None:
            time.sleep(0.01)
        victims = workers_of(proc.pid)
        if victims:
            victim = rng.choice(victims)
            os.kill(victim, getattr(signal, f"SIG{args.signal}"))
            killed = (victim, time.perf_counter() - t_start)
    rest, err = proc.communicate()
    elapsed = time.perf_counter() - t_start
    events += [json.loads(ln) for ln in rest.splitlines() if ln.startswith("{")]
    return proc.returncode, events, err, killed, elapsed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.worker_kill")
    ap.add_argument("--scene", type=Path, default=ROOT / "demo" / "demo.json")
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--resolution", default="240x135")
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--signal", default="KILL", choices=("KILL", "SEGV", "TERM", "ABRT"))
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from backend.imageio import read_exr
    work = Path(tempfile.mkdtemp(prefix="lamina-kill-"))
    code, events, err, _, t_ref = render(args.scene, work / "ref.exr", args)
    assert code == 0, err
    ref, names = read_exr(work / "ref.exr")
    start = events[0]
    print(f"reference: {args.scene.name} {args.resolution or ''} {args.spp or ''} spp, {start['workers']} workers "
          f"({start['parallel']}), {t_ref:.1f} s from start", flush=True)
    # Workers exist while items run: from the start event to the last progress event (the EXR
    # write and the exit come after). Moments are drawn from the first 90 % of that span.
    t_work = max([e["elapsed"] for e in events if e["event"] == "progress"] or [t_ref])
    rng = random.Random(args.seed)
    ok = 0
    for run in range(1, args.runs + 1):
        at = rng.uniform(0.0, 0.9 * t_work)
        out = work / f"run{run}.exr"
        code, events, err, killed, elapsed = render(args.scene, out, args, at, rng)
        while killed is None and code == 0 and at > 0.05:
            # This render ended before the moment (run times vary by ~10 %): nothing was
            # killed, so it tests nothing; again at half the moment.
            print(f"run {run:2d}: no worker left at {at:.2f} s (render ended at {elapsed:.1f} s); "
                  f"again at {at / 2:.2f} s", flush=True)
            at /= 2
            code, events, err, killed, elapsed = render(args.scene, out, args, at, rng)
        warnings = [e["message"] for e in events if e["event"] == "warning"]
        same = code == 0 and np.array_equal(read_exr(out)[0], ref)
        good = same and killed is not None and len(warnings) == 1
        ok += good
        print(f"run {run:2d}: SIG{args.signal} to worker {killed[0] if killed else '-'} at "
              f"{killed[1] if killed else at:6.2f} s -> exit {code}, {elapsed:5.1f} s, "
              f"{len(warnings)} warning(s), image {'bit-identical' if same else 'DIFFERENT'}"
              f"{'' if good else '  <-- FAIL'}", flush=True)
        if warnings:
            print(f"        {warnings[0]}")
        if code != 0:
            print("        " + err.strip().splitlines()[-1] if err.strip() else "")
    print(f"{ok}/{args.runs} runs complete and bit-identical (compared: every channel of the EXR, "
          f"{', '.join(names)})")
    return 0 if ok == args.runs else 1


if __name__ == "__main__":
    sys.exit(main())
