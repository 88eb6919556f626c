"""F12 wall time in Blender, Lamina against Cycles, and material preview latency (issue 38).

    .venv/bin/python -m benchmarks.f12_time [--rounds 4] [--resolution 320x180] [--spp 32]

In one bpy child process (the add-on loaded from this checkout, kernels warm): a small everyday
scene (tests/blender/cases/f12_cases.py: Principled ground, sphere and cube, a sun, a world
colour) rendered with F12 (``bpy.ops.render.render(write_still=True)``, the EXR written) by
Lamina through its warm render server, by Lamina with a new renderer process per render (the
Keep Renderer Warm preference off: the route before the server) and by Cycles on the CPU
(adaptive sampling and denoising off in both; Lamina's Denoise off), interleaved round by round
(ABC, CBA, ...). The first Lamina F12 (which starts the server) and Cycles' first render are
reported apart. Then three material previews in a row (the first starts the preview server;
Blender's UI starts it ahead, after the kernels are compiled). Prints medians and ratios to
Cycles, and the load average.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--resolution", default="320x180")
    ap.add_argument("--spp", type=int, default=32)
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.resolution.split("x"))
    sys.path.insert(0, str(REPO / "tests" / "blender"))
    from bpy_harness import run_cases
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="lamina-f12-") as tmp:
        r = run_cases("f12_cases", ["timings", "previews"], tmp=Path(tmp), timeout=1800,
                      args={"timings": {"rounds": args.rounds, "width": w, "height": h, "spp": args.spp}})
    t, pv = r["timings"], r["previews"]
    if "error" in t or "error" in pv:
        print(t.get("error") or pv.get("error"))
        return 1
    cycles = statistics.median(t["cycles"])
    print(f"F12, {w}×{h}, {args.spp} spp, {args.rounds} interleaved rounds (load average before "
          f"{load0[0]:.2f}, after {os.getloadavg()[0]:.2f}, {os.cpu_count()} cores)")
    print(f"{'':34} {'median s':>9} {'× Cycles':>9}   each")
    for name, key in (("Lamina, warm renderer", "warm"), ("Lamina, new process per render", "cold"),
                      ("Cycles", "cycles")):
        m = statistics.median(t[key])
        print(f"{name:34} {m:9.3f} {m / cycles:9.2f}   " + " ".join(f"{v:.3f}" for v in t[key]))
    print(f"first Lamina F12 of the session (starts the server): {t['first_warm']:.3f} s")
    print("material previews (128², seconds to first pixels / final): " + ", ".join(
        f"{p['first_pixels']:.2f}/{p['final']:.2f}" for p in pv["previews"])
          + " (the first starts the preview server)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
