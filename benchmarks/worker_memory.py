"""Peak memory of a render against the number of workers (issue 18, item 6).

    python -m benchmarks.worker_memory [--triangles 3369608] [--workers 1 2] [--kind threads processes]

Renders a scene holding one big mesh (a displaced grid, default 1298² × 2 = 3.37 M triangles, with
per-vertex normals and UVs, written once as .npz) at 64 × 64 pixels, 1 sample, with each worker
count: ``threads`` uses a diffuse material and worker threads (they share one scene and one BVH),
``processes`` a two-interface layered stack and ``--parallel processes`` (forked on Linux after
the scene and BVH are built, so they share them; spawned with LAMINA_WORKER_START=spawn, each
loading the scene and building its own BVH). A sampler reads the proportional set size (PSS, /proc/PID/smaps_rollup:
shared pages split between the processes sharing them) and the RSS of the render process and
all its descendants every 50 ms; the peak of their sums is the render's peak memory. The
process's own ru_maxrss (self, and largest child) is printed too.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from .procs import render_workers, tree

ROOT = Path(__file__).resolve().parent.parent


def grid_mesh(path: Path, n: int) -> int:
    """An n × n quad grid (2n² triangles), gently displaced, with normals and UVs."""
    if path.exists():
        with np.load(path) as d:
            return int(d["indices"].shape[0])
    t = np.linspace(0.0, 1.0, n + 1)
    u, v = np.meshgrid(t, t, indexing="ij")
    z = 0.05 * np.sin(12 * u) * np.cos(9 * v)
    pos = np.stack([4 * u - 2, 4 * v - 2, z], axis=-1).reshape(-1, 3).astype(np.float32)
    dzdu = 0.05 * 12 * np.cos(12 * u) * np.cos(9 * v) / 4
    dzdv = -0.05 * 9 * np.sin(12 * u) * np.sin(9 * v) / 4
    nrm = np.stack([-dzdu, -dzdv, np.ones_like(z)], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, c = a + 1, a + n + 1
    d = c + 1
    idx = np.concatenate([np.stack([a, c, d], 1), np.stack([a, d, b], 1)]).astype(np.int32)
    np.savez(path, positions=pos, indices=idx, normals=nrm.reshape(-1, 3).astype(np.float32),
             uvs=np.stack([u, v], -1).reshape(-1, 2).astype(np.float32))
    return int(idx.shape[0])


def scene(mesh: str, layered: bool, spp: int = 1) -> dict:
    """The grid under a layered (or diffuse) material, 64² at ``spp`` samples per pixel."""
    mat = ({"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.1},
                                             {"type": "diffuse", "color": [0.6, 0.4, 0.3]}],
            "media": [{"thickness": 0.1, "sigma_t": 1.0, "albedo": 0.8}]}
           if layered else {"type": "diffuse", "color": [0.6, 0.4, 0.3]})
    return {"format": "lamina-scene", "version": 1, "film": {"width": 64, "height": 64},
            "camera": {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]],
                       "frame": [[0.5, 0.5, -1], [0.5, -0.5, -1], [-0.5, -0.5, -1], [-0.5, 0.5, -1]]},
            "render": {"spp": spp, "max_bounces": 2},
            "materials": {"m": mat}, "meshes": {"grid": {"file": mesh}},
            "objects": [{"mesh": "grid", "materials": ["m"]}],
            "world": {"type": "constant", "color": [1, 1, 1], "strength": 1}}


def _mem(pid: int) -> tuple[int, int]:
    """(PSS, RSS) in bytes of one process (0, 0 if gone)."""
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            pss = rss = 0
            for line in f:
                if line.startswith("Pss:"):
                    pss = int(line.split()[1]) * 1024
                elif line.startswith("Rss:"):
                    rss = int(line.split()[1]) * 1024
            return pss, rss
    except OSError:
        return 0, 0


def measure(scene_path: Path, workers: int, out: Path, parallel: str = "threads") -> dict:
    code = ("import resource, runpy, sys; sys.argv = ['backend'] + sys.argv[1:]; "
            "from backend import cli; rc = cli.main(sys.argv[1:]); "
            "s = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss; "
            "c = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss; "
            "print('MAXRSS', s, c, file=sys.stderr); sys.exit(rc)")
    proc = subprocess.Popen([sys.executable, "-c", code, "render", str(scene_path), "-o", str(out),
                             "--workers", str(workers), "--parallel", parallel, "--progress", "json"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peak = {"pss": 0, "rss": 0, "procs": 0, "pss_with_workers": 0}
    done = threading.Event()

    def sample():
        while not done.is_set():
            pids = tree(proc.pid)
            mem = [_mem(p) for p in pids]
            pss, rss = sum(m[0] for m in mem), sum(m[1] for m in mem)
            alive = len([m for m in mem if m[1]])
            if pss > peak["pss"]:
                peak.update(pss=pss, procs=alive)
            if len(render_workers(pids[1:])) >= 2:
                peak["pss_with_workers"] = max(peak["pss_with_workers"], pss)
            peak["rss"] = max(peak["rss"], rss)
            time.sleep(0.05)

    th = threading.Thread(target=sample, daemon=True)
    t0 = time.perf_counter()
    th.start()
    stdout, stderr = proc.communicate()
    done.set()
    th.join()
    if proc.returncode != 0:
        raise RuntimeError(stderr)
    start = next(json.loads(ln) for ln in stdout.splitlines() if '"start"' in ln)
    maxrss = next(ln.split()[1:] for ln in stderr.splitlines() if ln.startswith("MAXRSS"))
    return {"workers": workers, "parallel": start["parallel"], "seconds": time.perf_counter() - t0,
            "peak_pss": peak["pss"], "peak_rss": peak["rss"], "processes_at_peak": peak["procs"],
            "peak_pss_while_workers": peak["pss_with_workers"],
            "maxrss_self": int(maxrss[0]) * 1024, "maxrss_largest_child": int(maxrss[1]) * 1024}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.worker_memory")
    ap.add_argument("--grid", type=int, default=1298, help="grid size n (2n² triangles)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--kind", nargs="+", default=["threads", "processes"], choices=("threads", "processes"))
    ap.add_argument("--cache", type=Path, default=Path(__file__).resolve().parent / ".cache")
    args = ap.parse_args(argv)
    args.cache.mkdir(parents=True, exist_ok=True)
    mesh = args.cache / f"grid{args.grid}.npz"
    tris = grid_mesh(mesh, args.grid)
    print(f"mesh: {tris} triangles ({mesh.stat().st_size / 2**20:.0f} MiB .npz)")
    work = Path(tempfile.mkdtemp(prefix="lamina-mem-"))
    rows = []
    for kind in args.kind:
        path = work / f"{kind}.json"
        path.write_text(json.dumps(scene(str(mesh), kind == "processes")))
        for w in args.workers:
            r = measure(path, w, work / "out.exr", kind)
            rows.append((kind, r))
            print(f"{kind:9s} workers={w}: {r['parallel']:9s} peak PSS {r['peak_pss'] / 2**30:5.2f} GiB, "
                  f"({r['processes_at_peak']} processes; while worker processes ran: "
                  f"{r['peak_pss_while_workers'] / 2**30:5.2f} GiB), peak RSS sum {r['peak_rss'] / 2**30:5.2f} GiB, "
                  f"ru_maxrss self {r['maxrss_self'] / 2**30:5.2f} GiB, largest child "
                  f"{r['maxrss_largest_child'] / 2**30:5.2f} GiB, {r['seconds']:.0f} s", flush=True)
    for kind in args.kind:
        base = next(r for k, r in rows if k == kind and r["workers"] == args.workers[0])
        for k, r in rows:
            if k == kind and r is not base:
                print(f"{kind}: peak PSS with {r['workers']} workers = "
                      f"{r['peak_pss'] / base['peak_pss']:.2f} × that with {base['workers']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
