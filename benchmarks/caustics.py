"""Caustics traced from the lights against path tracing them (backend/kernels/caustics.py).

A glass ball (``--ball gold``: a rough gold one) on a diffuse floor under a 5° sun and a small
area light (``--lamp point``: a small point light instead; the caustics fall in view), rendered with ``caustic_photons`` 0 (path traced only) and the values given, interleaved
over ``--rounds`` passes: per variant, the image's summed per-pixel variance over ``--seeds``
renders, the CPU per render (this process, one worker) and their product (lower is better at
equal time). ``--demo`` adds the demo scene's noise figures (benchmarks/everyday.py's: image-wide
and median pixel) with and without photons, 4 seeds at 32 spp, two workers.

    .venv/bin/python -m benchmarks.caustics [--size 128] [--spp 16] [--seeds 6] [--photons 0.125,0.5] [--ball glass|gold] [--lamp sun+area|point] [--demo]
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from .scenes import REPO


#: The ball's material (``--ball``): smooth glass, or gold as Blender's Principled BSDF exports
#: it at Metallic 1, Roughness 0.3 (α 0.09: a caster as a metal, backend/caustics.py).
BALLS = {"glass": {"type": "dielectric", "ior": 1.5, "roughness": 0.0},
         "gold": {"type": "conductor", "metal": "Au", "roughness": 0.09}}


#: ``--lamp point``: instead of the sun and the area light, Blender's default point light (a
#: soft-falloff disk of radius 0.1 m) where the area light was.
POINT_LAMP = {"type": "point", "power": 100.0, "radius": 0.1, "soft_falloff": True,
              "to_world": [[1, 0, 0, 0.0], [0, 1, 0, 1.2], [0, 0, 1, 2.0], [0, 0, 0, 1]]}


def glass_ball_scene(size: int, spp: int, seed: int, photons: float, ball: str = "glass",
                     lamp: str = "sun+area") -> dict:
    """The scene of docs/benchmarks.md's caustics figures (fifth session, 2026-12-07)."""
    floor = {"positions": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], "indices": [[0, 1, 2], [0, 2, 3]]}
    data = {"format": "lamina-scene", "version": 1, "film": {"width": size, "height": size},
            "camera": {"type": "perspective",
                       "to_world": [[1, 0, 0, 0], [0, 0.6, -0.8, -3.2], [0, 0.8, 0.6, 3.0], [0, 0, 0, 1]],
                       "frame": [[0.45, 0.45, -1], [0.45, -0.45, -1], [-0.45, -0.45, -1], [-0.45, 0.45, -1]]},
            "materials": {"ball": BALLS[ball], "floor": {"type": "diffuse", "color": [0.7, 0.7, 0.7]}},
            "meshes": {"ball": {"shape": "sphere", "radius": 0.5, "segments": 48}, "floor": floor},
            "objects": [{"name": "ball", "mesh": "ball", "materials": ["ball"],
                         "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.6], [0, 0, 0, 1]]},
                        {"name": "floor", "mesh": "floor", "materials": ["floor"]}],
            "lights": [{"type": "sun", "strength": 3.0, "angle": 5.0,
                        "to_world": [[1, 0, 0, 0], [0, 0.8, 0.6, 0], [0, -0.6, 0.8, 10], [0, 0, 0, 1]]},
                       {"type": "area", "shape": "rectangle", "size": 0.6, "size_y": 0.4, "power": 60.0,
                        "to_world": [[1, 0, 0, 0.0], [0, 1, 0, 1.2], [0, 0, 1, 2.0], [0, 0, 0, 1]]}],
            "world": {"type": "constant", "color": [0.2, 0.25, 0.3]},
            "render": {"spp": spp, "max_bounces": 6, "seed": seed, "caustic_photons": photons}}
    if lamp == "point":
        data["lights"] = [POINT_LAMP]
    return data


def _glass_ball(args) -> None:
    from .measure import render
    variants = [0.0] + [float(v) for v in args.photons.split(",")]
    out: dict = {}
    for _ in range(args.rounds):
        for ph in variants:
            imgs, cpu = [], 0.0
            for s in range(args.seeds):
                t0 = time.process_time()
                r = render(glass_ball_scene(args.size, args.spp, 300 + s, ph, args.ball, args.lamp), args.spp,
                           seed=300 + s, workers=1)
                cpu += time.process_time() - t0
                imgs.append(r.image[..., :3])
            var = float(np.stack(imgs).var(axis=0, ddof=1).sum())
            out.setdefault(ph, []).append((var, cpu / args.seeds))
    print(f"{args.ball} ball on a floor ({args.lamp}), {args.size}², {args.spp} spp, {args.seeds} seeds, load {os.getloadavg()[0]:.2f}")
    for ph, runs in out.items():
        cells = "  ".join(f"variance {v:9.1f}  CPU {c:6.3f} s  product {v * c:9.1f}" for v, c in runs)
        print(f"  caustic_photons {ph:5.3f}: {cells}")


def _demo(args) -> None:
    from .everyday import LUM, noise_figures
    from .measure import render
    data = json.loads((REPO / "demo" / "demo.json").read_text())
    here = os.getcwd()
    os.chdir(REPO / "demo")                  # the demo's texture paths are relative to it
    try:
        for ph in (0.0, float(args.photons.split(",")[0])):
            d = json.loads(json.dumps(data))
            d["render"]["caustic_photons"] = ph
            runs = [render(d, 32, seed=1000 + s, workers=2) for s in range(4)]
            f = noise_figures(np.stack([r.image[..., :3] @ LUM for r in runs]))
            print(f"demo, caustic_photons {ph:5.3f}: image-wide {100 * f['relative_noise']:.2f} %, "
                  f"median pixel {100 * f['typical_pixel_noise']:.2f} %, "
                  f"CPU per render {np.mean([r.cpu for r in runs]):.2f} s")
    finally:
        os.chdir(here)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--photons", default="0.125,0.5", help="comma-separated caustic_photons besides 0")
    ap.add_argument("--ball", choices=sorted(BALLS), default="glass")
    ap.add_argument("--lamp", choices=("sun+area", "point"), default="sun+area")
    ap.add_argument("--demo", action="store_true")
    args = ap.parse_args(argv)
    _glass_ball(args)
    if args.demo:
        _demo(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
