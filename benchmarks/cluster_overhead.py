"""What running work items as Dask tasks costs (issue 21, docs/cluster.md).

    python -m benchmarks.cluster_overhead [--scene demo/demo.json] [--resolution 160x90] [--spp 8]
                                          [--sizes 4096,16384,65536] [--repeats 2]

For each work item size (paths per item, ``render.LANES_PER_ITEM``) it renders the scene
* locally on one thread (the reference: the same items, no Dask),
* on a local Dask cluster of 1 worker process (1 thread), and of 2 worker processes,
and prints per size: the items, the wall times [s], the fixed cost per render [s] (connecting,
the file check), the overhead per task [ms] = (1-worker cluster − local − fixed) / items, the
whole overhead in % of the local time, and the speed-up of 2 workers over 1. Then the smallest item size whose overhead stays under 5 % (smaller items cost more per
path: the overhead per task is roughly constant), and the speed-up predicted for a cluster of
``--machines`` × ``--threads`` workers (4 × 16) on the scene at full size: the schedule simulated
by benchmarks/parallel_scaling.py, with the per-task overhead measured at the renderer's item
size counted as serial work of the scheduler (a pessimistic reading: part of it is the workers'). Every cluster image is checked bit-identical to
the local one. The clusters are started before timing, and each timed render is a second render
of the same scene (its files are cached and its scene loaded on the workers), as in a sequence of
frames; wall times are the best of ``--repeats``.
"""
from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _render(path: Path, resolution, spp: int, **options):
    from backend.render import Renderer, RenderOptions
    from backend.scene.loader import load_scene
    scene = load_scene(path)
    opts = RenderOptions(spp=spp, resolution=resolution, **options)
    opts.apply(scene)
    t0 = time.perf_counter()
    result = Renderer(scene, str(path), opts).run()
    wall = time.perf_counter() - t0
    if result.error:
        raise SystemExit(f"render failed: {result.error}")
    return wall, result


def _item_count(pixels: int, spp: int) -> int:
    """Work items of a render without adaptive sampling (render.Renderer.run's plan)."""
    from backend.render import choose_spp_block, plan_round
    block = choose_spp_block(pixels, spp)
    active = np.arange(pixels)
    count = 0
    for r in range(-(-spp // block)):
        count += len(plan_round(active, min(block, spp - r * block), r, 0, r * block))
    return count


def _connect_time(path: Path, resolution, spp: int, address: str) -> float:
    """The fixed cost of a cluster render: connecting a client, asking the workers for missing
    files (none here) and closing, without any item."""
    from backend.cluster import ClusterItems
    from backend.render import RenderOptions
    from backend.scene.loader import load_scene
    scene = load_scene(path)
    opts = RenderOptions(spp=spp, resolution=resolution, cluster=address)
    opts.apply(scene)
    t0 = time.perf_counter()
    runner = ClusterItems(address, scene, str(path), opts, print)
    runner.close(stopped=False)
    return time.perf_counter() - t0


def _best(repeats: int, fn):
    runs = [fn() for _ in range(repeats)]
    return min(r[0] for r in runs), runs[-1][1]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default=str(ROOT / "demo" / "demo.json"))
    parser.add_argument("--resolution", default="160x90", help="WxH")
    parser.add_argument("--spp", type=int, default=8)
    parser.add_argument("--sizes", default="4096,16384,65536", help="paths per work item, comma-separated")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--machines", type=int, default=4, help="machines of the predicted cluster")
    parser.add_argument("--threads", type=int, default=16, help="worker threads per machine")
    parser.add_argument("--predict-spp", type=int, default=64, help="spp of the predicted full-size render")
    args = parser.parse_args(argv)
    import backend  # noqa: F401 - one BLAS thread per process, before NumPy's first use
    import backend.render as render_module
    from backend.cluster import close_connection, connect
    default_size = render_module.LANES_PER_ITEM
    resolution = tuple(int(v) for v in args.resolution.lower().split("x"))
    path = Path(args.scene)
    sizes = [int(s) for s in args.sizes.split(",")]
    rows = []
    clusters = {n: connect(f"local:{n}") for n in (1, 2)}
    try:
        addresses = {n: c[1].scheduler_address for n, c in clusters.items()}
        logging.getLogger("distributed").setLevel(logging.CRITICAL + 1)
        _render(path, resolution, args.spp, workers=1)       # warm: kernels, caches, page cache
        for size in sizes:
            render_module.LANES_PER_ITEM = size
            local, reference = _best(args.repeats, lambda: _render(path, resolution, args.spp, workers=1))
            walls = {}
            for n in (1, 2):
                _render(path, resolution, args.spp, cluster=addresses[n])        # files, scene load
                walls[n], result = _best(args.repeats,
                                         lambda: _render(path, resolution, args.spp, cluster=addresses[n]))
                same = (np.array_equal(result.film.sum, reference.film.sum)
                        and np.array_equal(result.film.count, reference.film.count))
                if not same:
                    raise SystemExit(f"item size {size}, {n} worker(s): the image differs from the local render")
            items = _item_count(reference.film.width * reference.film.height, args.spp)
            fixed = min(_connect_time(path, resolution, args.spp, addresses[1]) for _ in range(args.repeats))
            overhead = walls[1] - local
            rows.append((size, items, local, walls[1], walls[2], fixed,
                         1000 * max(overhead - fixed, 0.0) / items, 100 * overhead / local,
                         walls[1] / walls[2]))
    finally:
        render_module.LANES_PER_ITEM = default_size
        for client, cluster in clusters.values():
            close_connection(client, cluster)
    print(f"scene {path.name} at {resolution[0]}x{resolution[1]}, {args.spp} spp; best of {args.repeats}; "
          f"images bit-identical to the local render in every case")
    print(f"{'paths/item':>10} {'items':>6} {'local 1 [s]':>11} {'dask 1 [s]':>10} {'dask 2 [s]':>10} "
          f"{'per render [s]':>14} {'per task [ms]':>13} {'overhead [%]':>12} {'speed-up 2/1':>12}")
    for size, items, local, one, two, fixed, per_task, percent, speedup in rows:
        print(f"{size:>10} {items:>6} {local:>11.3f} {one:>10.3f} {two:>10.3f} {fixed:>14.3f} "
              f"{per_task:>13.1f} {percent:>12.1f} {speedup:>12.2f}")
    print("overhead [%] = (dask 1 - local 1) / local 1, both on one thread; per render = connecting "
          "and the file check; per task = the rest / items")
    under = [r[0] for r in rows if r[7] < 5.0]
    print("smallest item size with overhead < 5 %: " + (f"{min(under)} paths" if under else
                                                        "none of those measured"))
    _predict(rows, args, default_size)
    return 0


def _predict(rows, args, size: int) -> None:
    """The speed-up ``--machines`` × ``--threads`` cluster workers would give on the scene at full
    size (``--predict-spp``), simulated (benchmarks/parallel_scaling.py) with the measured
    per-task overhead at the renderer's item size counted as serial scheduler work."""
    import tempfile

    from .parallel_scaling import predict, record
    measured = {r[0]: r[6] / 1000.0 for r in rows}
    per_task = measured.get(size, max(measured.values()) if measured else 0.0)
    rec = record("cluster", Path(tempfile.mkdtemp()), Path(args.scene), args.predict_spp, None)
    workers = args.machines * args.threads
    pred = predict(rec, [16, workers], per_task)
    print(f"predicted on {args.machines} machines × {args.threads} worker threads ({workers} workers), "
          f"{Path(args.scene).name} at full size, {args.predict_spp} spp, {len(rec.items)} items of {size} "
          f"paths, {1000 * per_task:.1f} ms serial per task: {pred[workers]:.1f}× one local thread "
          f"(16 workers: {pred[16]:.1f}×)")


if __name__ == "__main__":
    raise SystemExit(main())
