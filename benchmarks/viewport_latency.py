"""Viewport latency on the demo scene (issue 20's acceptance figures).

    python -m benchmarks.viewport_latency [--repeats 3] [--width 960 --height 540] [--samples 4]

Runs ``tests/blender/cases/viewport_cases.demo_latency`` in a headless bpy process (the dev
environment's ``bpy`` module): the add-on's Rendered-mode engine drives a real backend session
on the demo scene (rebuilt in Blender), with a stand-in for the GPU drawing call (headless
Blender cannot draw). Per repeat it measures, in wall seconds from the Blender-side call:

* first image after entering Rendered mode (warm kernel cache; a pre-started standby session, as
  the add-on keeps one by default, or with --no-standby a renderer process started then),
* first updated image drawn after a 2° view orbit,
* first updated image drawn after a stack edit (the top interface's IOR),
* the session's CPU use (process + children) over 5 s once the viewport sample count is reached.

The kernel cache is the user's (LAMINA_KERNEL_CACHE or the default folder): run a render once
before so that it is warm, as the acceptance asks.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.viewport_latency")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=540)
    ap.add_argument("--samples", type=int, default=4, help="Viewport Samples")
    ap.add_argument("--no-standby", action="store_true",
                    help="no pre-started session: entering Rendered mode starts the renderer process")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "tests" / "blender"))
    from bpy_harness import run_cases
    tmp = Path(tempfile.mkdtemp(prefix="lamina-vp-latency-"))
    res = run_cases("viewport_cases", ["demo_latency"], tmp=tmp, timeout=1800,
                    args={"demo_latency": {"width": args.width, "height": args.height,
                                           "samples": args.samples, "repeats": args.repeats,
                                           "standby": not args.no_standby}})
    runs = res["demo_latency"]
    if isinstance(runs, dict) and "error" in runs:
        print(runs["error"], file=sys.stderr)
        return 1
    load = os.getloadavg()
    print(f"viewport latency, demo scene {args.width}×{args.height}, Viewport Samples {args.samples}, "
          f"{'no standby session' if args.no_standby else 'pre-started standby session'}, {len(runs)} repeats (load at end {load[0]:.2f} {load[1]:.2f})")

    def row(label, key, unit="s", scale=1.0, goal=""):
        vals = [r[key] * scale for r in runs]
        print(f"  {label:38s} median {statistics.median(vals):7.3f} {unit}  [min {min(vals):.3f} – "
              f"max {max(vals):.3f}]  {goal}")

    row("first image after entering Rendered", "first", goal="(goal ≤ 1 s)")
    row("  of which export and send", "export_and_send")
    row("first updated image after a view move", "move", goal="(goal ≤ 0.3 s)")
    row("first updated image after a stack edit", "edit", goal="(goal ≤ 0.5 s)")
    row("session CPU once idle", "idle_cpu_fraction", unit="%", scale=100.0, goal="(goal < 5 %)")
    print(f"  first image's resolution divisor: {sorted({r['first_scale'] for r in runs})}; "
          f"stack edit rebuilt: {runs[-1]['edit_rebuilt']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
