"""The layered BSDF's MIS density in renders: render CPU time and noise of the pdf kinds.

The pdf of a layered stack feeds only MIS weights, so every kind gives the same expected image;
what differs is the cost of the estimate and the variance a poor density leaves in the image.
Per stack and light, one worker renders a sphere filling the frame (the `layered_throughput`
scene: a sphere light of radius 0.3 m, or a 2.5 m square area light close by that reflects in
much of the sphere, which is where MIS weights matter) with each kind, ``--rounds`` rounds
interleaved (ABAB) with different seeds; it prints the median render CPU time, the mean over pixels
of the per-pixel variance of the mean (film.variance_of_mean, from the samples themselves), and the
efficiency 1/(variance × CPU) of each kind against the approximate pdf, and the images' means (they
must agree within noise).

    .venv/bin/python benchmarks/layered_mis_pdf.py [--kinds lobes,approx] [--size 96] [--spp 16]
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from layered_throughput import STACKS, _sphere_scene, render_cpu  # noqa: E402

EXTRA = {
    # A smooth clear coat over brushed gold: the anisotropic lobe is seen through a sharp refraction.
    "clear-over-brushed": {"type": "layered",
                           "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.0},
                                          {"type": "conductor", "metal": "Au", "roughness": 0.05,
                                           "roughness_v": 0.3}],
                           "media": [{"sigma_t": 0.3, "albedo": 0.8, "phase": {"type": "hg", "g": 0.5}}]},
    # A rough coat over a near-mirror: the inner lobe is spread by the refractions.
    "rough-over-sharp": {"type": "layered",
                         "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.3},
                                        {"type": "conductor", "metal": "Cu", "roughness": 0.02}],
                         "media": [{"sigma_t": 0.1, "albedo": 0.5}]},
    # A transmissive sheet: a rough coat over clear glass (one rough interface: transmissions in
    # closed form too).
    "rough-coat-over-glass": {"type": "layered",
                              "interfaces": [{"type": "dielectric", "ior": 1.4, "roughness": 0.35},
                                             {"type": "dielectric", "ior": 1.0, "roughness": 0.0}],
                              "media": [{"sigma_t": 0.4, "albedo": 0.9, "phase": {"type": "hg", "g": 0.6}}]},
}
AREA = {"type": "area", "shape": "square", "size": 2.5, "power": 800.0,
        "to_world": [[1, 0, 0, 1.5], [0, 0.707, -0.707, -2.0], [0, 0.707, 0.707, 2.0], [0, 0, 0, 1]]}


def scene(material: dict, light: str, size: int, spp: int, seed: int) -> dict:
    d = _sphere_scene(material, size, spp)
    d["render"]["seed"] = seed
    if light == "area":
        d["lights"] = [dict(AREA)]
    return d


def compare(material: dict, light: str, kinds, size: int, spp: int, rounds: int) -> dict:
    out = {k: {"cpu": [], "var": [], "mean": []} for k in kinds}
    for k in kinds:                                   # kernels loaded outside the timing
        render_cpu(scene({**material, "pdf": k}, light, 8, 1, 1))
    for r in range(rounds):
        for k in (kinds if r % 2 == 0 else kinds[::-1]):
            cpu, _, res = render_cpu(scene({**material, "pdf": k}, light, size, spp, 11 + r))
            out[k]["cpu"].append(cpu)
            out[k]["var"].append(float(res.film.variance_of_mean().reshape(-1, 3).mean()))
            out[k]["mean"].append(float(res.film.combined().reshape(-1, 3).mean()))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kinds", default="lobes,approx")
    ap.add_argument("--stacks", nargs="*", default=None, help="stacks whose names contain one of these (default: all)")
    ap.add_argument("--lights", default="point,area")
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    kinds = args.kinds.split(",")
    base = "approx" if "approx" in kinds else kinds[0]
    stacks = {**STACKS, **EXTRA}
    print(f"{args.size}², {args.spp} spp, one worker, {args.rounds} interleaved rounds; load "
          f"{os.getloadavg()[0]:.2f}. CPU s (median), pixel variance of the mean (mean over pixels), "
          f"efficiency 1/(variance × CPU) against {base}, image mean")
    names = [n for n in stacks if args.stacks is None or any(w in n for w in args.stacks)]
    for name in names:
        for light in args.lights.split(","):
            r = compare(stacks[name], light, kinds, args.size, args.spp, args.rounds)
            cpu = {k: float(np.median(r[k]["cpu"])) for k in kinds}
            var = {k: float(np.mean(r[k]["var"])) for k in kinds}
            row = "  ".join(f"{k} {cpu[k]:.2f} s {var[k]:.3e} ×{var[base] * cpu[base] / (var[k] * cpu[k]):.2f} "
                            f"mean {np.mean(r[k]['mean']):.4f}" for k in kinds)
            print(f"  {name:20s} {light:6s} {row}", flush=True)


if __name__ == "__main__":
    main()
