"""How many bounces need stratified (Sobol) numbers: error at equal samples and CPU time for
Sobol on the first k bounces (hashed numbers deeper), k = 0 (independent) … all.

    .venv/bin/python -m benchmarks.sampler_depth [--size 48] [--spp 16 64] [--seeds 3]

Scenes: the Cornell-like box with diffuse spheres (indirect light matters) and with its rough
gold and smooth glass spheres. RMSE against a 4096-spp independent-sampler reference (its own
noise subtracted); CPU time per render (thread time, warm kernels).
"""
from __future__ import annotations

import argparse
import copy
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from backend import integrator  # noqa: E402
from render_util import render  # noqa: E402

from .scenes import cornell_box  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--spp", type=int, nargs="+", default=[16, 64])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args(argv)
    for label, diffuse in (("diffuse spheres", True), ("gold + glass", False)):
        base = cornell_box(args.size, args.size, 16, 6)
        if diffuse:
            base["materials"]["gold"] = {"type": "diffuse", "color": [0.8, 0.6, 0.2]}
            base["materials"]["glass"] = {"type": "diffuse", "color": [0.7, 0.7, 0.7]}

        def run(spp, sampler, seed, k):
            integrator.STRATIFIED_BOUNCES = k
            d = copy.deepcopy(base)
            d["render"].update(spp=spp, sampler=sampler, seed=seed)
            t0 = time.thread_time()
            r = render(d, workers=1)
            return r, time.thread_time() - t0

        ref, _ = run(4096, "independent", 99, 64)
        ref_img = ref.film.combined()
        ref_mse = ref.film.variance_of_mean().mean()
        print(f"{label}: {args.size}², reference 4096 spp (noise RMSE {np.sqrt(ref_mse):.5f})")
        for spp in args.spp:
            for k in (0, 1, 2, 3, 64):
                sampler = "independent" if k == 0 else "sobol"
                errs, cpu = [], []
                for s in range(args.seeds):
                    r, c = run(spp, sampler, s + 1, k)
                    errs.append(np.mean((r.film.combined() - ref_img) ** 2) - ref_mse)
                    cpu.append(c)
                name = "independent" if k == 0 else ("sobol, all bounces" if k == 64 else f"sobol, {k} bounce(s)")
                print(f"  spp {spp:4d}  {name:20s} RMSE {np.sqrt(max(np.mean(errs), 0)):.5f}  "
                      f"CPU {np.median(cpu):.3f} s")
    integrator.STRATIFIED_BOUNCES = 64
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
