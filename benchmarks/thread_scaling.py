"""Wall time of 2 worker threads against 1 (issue 15: "2-way parallel wall time ≤ 0.6× the 1-way
time on the Cornell box at 64 spp and on a 1M-triangle scene at 4 spp, start-up included").

    .venv/bin/python -m benchmarks.thread_scaling [--repeat 3] [--grid 708] [--grid-film 256]

Each case is a whole ``python -m backend render`` (interpreter, imports, kernel load from a warm
cache, scene load, BVH build, render, EXR write), run with ``--workers 1`` and ``--workers 2``
alternately (1 2 2 1 1 2 …) so that a change of the machine's load hits both. Scenes: the
Cornell-like box (256², 64 spp) and a displaced grid of 2·n² triangles (n = 708: 1.0 M) with
per-vertex normals, a diffuse material and a sun, 4 spp at 256² (``--grid-film``: another square
size; at 256² the render is ≈ 0.3 s of ≈ 2.5 s, so the start-up decides the ratio).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .scenes import REPO, cornell_box
from .worker_memory import grid_mesh


def grid_scene(mesh: Path, size: int = 256, spp: int = 4) -> dict:
    cam = {"type": "perspective",
           "to_world": [[1, 0, 0, 0], [0, 0, -1, -3.0], [0, 1, 0, 1.2], [0, 0, 0, 1]],
           "frame": [[0.4, 0.4, -1], [0.4, -0.4, -1], [-0.4, -0.4, -1], [-0.4, 0.4, -1]]}
    return {"format": "lamina-scene", "version": 1, "film": {"width": size, "height": size},
            "camera": cam, "render": {"spp": spp, "max_bounces": 4, "seed": 1},
            "materials": {"m": {"type": "diffuse", "color": [0.6, 0.6, 0.6]}},
            "meshes": {"grid": {"file": str(mesh)}},
            "objects": [{"mesh": "grid", "materials": ["m"]}],
            "lights": [{"type": "sun", "to_world": [[1, 0, 0, 0], [0, 0.8, -0.6, 0], [0, 0.6, 0.8, 0], [0, 0, 0, 1]],
                        "strength": 3.0, "angle": 2.0}],
            "world": {"type": "constant", "color": [0.3, 0.35, 0.4], "strength": 0.5}}


def run(scene: Path, workers: int, out: Path) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(scene), "-o", str(out),
                           "--workers", str(workers), "--progress", "none"], cwd=REPO,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(proc.stderr)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--grid", type=int, default=708)
    ap.add_argument("--grid-film", type=int, default=256, help="film size of the grid scene (square)")
    ap.add_argument("--cases", default="cornell,grid", help="comma-separated: cornell, grid")
    ap.add_argument("--cache", type=Path, default=Path(__file__).resolve().parent / ".cache")
    args = ap.parse_args(argv)
    args.cache.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="lamina-scaling-"))
    cornell = work / "cornell.json"
    cornell.write_text(json.dumps(cornell_box(256, 256, spp=64)))
    mesh = args.cache / f"grid{args.grid}.npz"
    tris = grid_mesh(mesh, args.grid)
    grid = work / "grid.json"
    grid.write_text(json.dumps(grid_scene(mesh, args.grid_film)))
    print(f"wall seconds of whole renders, 1 vs 2 worker threads, {args.repeat} interleaved pairs "
          f"(load at start {os.getloadavg()[0]:.2f})")
    cases = {"cornell": ("Cornell box 256², 64 spp", cornell),
             "grid": (f"grid {tris / 1e6:.2f} M triangles, {args.grid_film}², 4 spp", grid)}
    for label, scene in (cases[c] for c in args.cases.split(",")):
        run(scene, 1, work / "out.exr")                 # warm the OS file cache
        times = {1: [], 2: []}
        for r in range(args.repeat):
            for w in ((1, 2) if r % 2 == 0 else (2, 1)):
                times[w].append(run(scene, w, work / "out.exr"))
        one, two = statistics.median(times[1]), statistics.median(times[2])
        ratios = sorted(b / a for a, b in zip(times[1], times[2]))
        print(f"  {label:40s} 1 worker {one:6.2f} s, 2 workers {two:6.2f} s: ratio {two / one:.3f} "
              f"(pairs {', '.join(f'{x:.3f}' for x in ratios)}; goal ≤ 0.6)", flush=True)
    print(f"  load at end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
