"""Sobol vs independent numbers on the layered validation scenes (issue 17: "RMSE at equal spp not
worse than with the independent sampler").

    .venv/bin/python -m benchmarks.sampler_layered [--size 48] [--spp 16 64] [--seeds 4] [--ref-spp 2048]

Scenes: the paper's validation stacks 1–4 on a plane under a sphere light (benchmarks/scenes.py,
``validation_plane``). The layered walks draw from hashed numbers in either mode; Sobol covers the
path's own dimensions of the first bounce (pixel, light choice and position, BSDF lobe and
direction). RMSE over pixels and RGB against an independent-sampler reference at ``--ref-spp``
(its own noise, mean variance of the pixel means, subtracted), averaged (as MSE) over ``--seeds``
independent seeds per sampler; the spread is the standard error of that mean MSE.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from render_util import render  # noqa: E402

from .scenes import validation_plane  # noqa: E402


def _image(data, spp, seed, sampler):
    r = render(data, workers=2, spp=spp, seed=seed, sampler=sampler)
    return r.film.combined(), r.film.variance_of_mean()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--spp", type=int, nargs="+", default=[16, 64])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--stacks", type=int, nargs="+", default=[1, 2, 3, 4])
    args = ap.parse_args(argv)
    print(f"layered validation planes {args.size}², RMSE (reference noise removed), mean over "
          f"{args.seeds} seeds ± standard error; load {os.getloadavg()[0]:.2f}")
    for which in args.stacks:
        data = validation_plane(which, args.size)
        ref, ref_var = _image(data, args.ref_spp, 10_000, "independent")
        ref_mse = float(np.mean(ref_var))
        row = [f"validation {which}:"]
        for spp in args.spp:
            res = {}
            for sampler in ("independent", "sobol"):
                mses = []
                for s in range(args.seeds):
                    img, _ = _image(data, spp, 1 + s, sampler)
                    mses.append(float(np.mean((img - ref) ** 2)) - ref_mse)
                mses = np.array(mses)
                res[sampler] = (mses.mean(), mses.std(ddof=1) / np.sqrt(len(mses)))
            (mi, si), (ms, ss) = res["independent"], res["sobol"]
            ratio = np.sqrt(ms / mi)
            row.append(f"{spp} spp: independent {np.sqrt(mi):.4g}, sobol {np.sqrt(ms):.4g} "
                       f"(RMSE ratio {ratio:.3f}; MSE ± {si / mi * 100:.0f} % / {ss / ms * 100:.0f} %)")
        print("  " + " | ".join(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
