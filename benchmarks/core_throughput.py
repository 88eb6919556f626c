"""Ray-casting vs shading time of the path tracer on a Cornell-like box (issue: backend core).

Renders the scene in one process while recording every ray batch, then traces the same rays again
with embree alone. Prints embree-only rays/s (on the render's own rays), the full renderer's
paths/s and rays/s, and the shading overhead = (render time − embree time) / embree time.

    .venv/bin/python -m benchmarks.core_throughput [--size 256] [--spp 16]
"""
from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from backend.geometry.accel import Accelerator, retrace
from backend.integrator import PathTracer
from backend.render import choose_spp_block, plan_round
from backend.scene.loader import load_scene_data

from .scenes import cornell_box


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--max-bounces", type=int, default=6)
    ap.add_argument("--sampler", choices=("sobol", "independent"), default="sobol")
    args = ap.parse_args(argv)

    from backend.warmup import ensure_compiled, warm_up
    ensure_compiled()
    warm_up()                  # steady state: every kernel loaded before timing
    data = cornell_box(args.size, args.size, args.spp, args.max_bounces)
    data["render"]["sampler"] = args.sampler
    scene = load_scene_data(data, "<cornell>")
    accel = Accelerator(scene.soup)
    tracer = PathTracer(scene, accel)
    W = H = args.size
    pixels = np.arange(W * H, dtype=np.int64)
    block = choose_spp_block(pixels.size, args.spp)
    items = []
    for r in range(int(np.ceil(args.spp / block))):
        items += plan_round(pixels, min(block, args.spp - r * block), r, 1, r * block)

    def render_all():
        for key, band, spp, seed, sample0 in items:
            rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, *key])))
            tracer.render(band, spp, rng, sample0)

    # First pass: record the render's own rays (the recorder copies each batch, so it is not
    # timed); second pass, the same rays (counter-based random numbers): timed, no recorder.
    accel.recorder = []
    render_all()
    batches = accel.recorder
    accel.recorder = None
    t0 = time.perf_counter()
    c0 = time.process_time()
    render_all()
    t_render = time.perf_counter() - t0
    c_render = time.process_time() - c0
    rays = sum(b[1].shape[0] for b in batches)
    t_embree = min(retrace(accel, batches) for _ in range(2))
    c0 = time.process_time()
    retrace(accel, batches)
    c_embree = time.process_time() - c0
    paths = W * H * args.spp
    print(f"machine: {platform.machine()} {platform.processor() or ''}, 1 process, Python {platform.python_version()}, numpy {np.__version__}")
    print(f"scene: Cornell-like box {W}x{H}, {args.spp} spp, max_bounces {args.max_bounces}, {scene.soup.count} triangles, sampler {args.sampler}")
    print(f"render (1 process):   {t_render:8.3f} s  {paths / t_render / 1e3:9.1f} k paths/s  {rays / t_render / 1e6:6.2f} M rays/s  ({rays} rays, {rays / paths:.2f} per path)")
    print(f"embree only, same rays: {t_embree:6.3f} s  {rays / t_embree / 1e6:6.2f} M rays/s")
    print(f"CPU time (robust on a shared machine): render {c_render:.3f} s, embree only {c_embree:.3f} s")
    print(f"shading overhead: {(t_render - t_embree) / t_embree:.2f}x the ray-casting time by wall clock, "
          f"{(c_render - c_embree) / c_embree:.2f}x by CPU time (target <= 1x)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
