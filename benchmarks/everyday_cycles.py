"""Cycles' noise on the scenes of benchmarks/everyday.py (the issue's right-hand column): each scene
with Blender's Principled BSDF as an artist sets it, rendered by Cycles 5.0 through the peer
benchmark's converter (benchmarks/peers), same metric as everyday.py.

    .venv/bin/python -m benchmarks.everyday_cycles [--spp 32] [--seeds 4] [--size 64]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from . import everyday as ev

#: The Principled settings each Lamina scene stands for (Cycles renders these).
PRINCIPLED = {
    "principled ground": {"base_color": (0.4, 0.4, 0.4), "roughness": 0.5},
    # gold: Blender's gold-ish base colour, metallic, roughness 0.3 (α 0.09), coat roughness 0.1
    "coated gold sphere": {"base_color": (0.944, 0.776, 0.373), "metallic": 1.0, "roughness": 0.3,
                           "coat_weight": 1.0, "coat_roughness": 0.1},
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.everyday_cycles")
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--size", type=int, default=64)
    args = ap.parse_args(argv)
    from .peers.convert import prepare
    from .peers.cycles_process import CyclesProcess
    scenes = ev.scenes(args.size)
    with tempfile.TemporaryDirectory() as tmp, CyclesProcess() as cy:
        for name, p in PRINCIPLED.items():
            data = scenes[name]
            job = prepare(data, Path(tmp) / name.replace(" ", "_"), principled={"m": p})
            cy.build(job, 2)
            imgs, cpu = [], 0.0
            for s in range(args.seeds):
                img, c, _ = cy.render(args.spp, 1000 + s)
                imgs.append(img[..., :3] @ ev.LUM)
                cpu += c
            r = ev.noise_figures(np.stack(imgs))
            print(f"{name:22s} Cycles noise {100 * r['relative_noise']:6.2f} %   typical pixel "
                  f"{100 * r['typical_pixel_noise']:6.2f} %   mean {r['mean']:.5f}   "
                  f"cpu/render {cpu / args.seeds:.2f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
