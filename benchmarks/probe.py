"""One timed render in a fresh interpreter, for the "features cost nothing" A/B (sections.overhead).

    python -m benchmarks.probe --scene cornell --size 96 --spp 32 [--block]

``--block`` makes the optional feature modules unimportable before the backend is imported
(``sys.modules[name] = None``: the material/light registries skip modules that are not there),
so the render runs on a renderer without them. Prints one JSON line: cpu, wall, import time.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

#: Modules that implement optional features. Blocking their import (``sys.modules[name] = None``,
#: which the registries treat as "not written yet") gives the renderer without them.
FEATURE_MODULES = ["backend.layered.material", "backend.layered.bsdf", "backend.layered.walk",
                   "backend.layered.medium", "backend.layered.phase", "backend.ies.light", "backend.ies.profile",
                   "backend.lights.environment", "backend.lights.point", "backend.lights.spot", "backend.lights.sun"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="cornell")
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--block", action="store_true")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    if args.block:
        for name in FEATURE_MODULES:
            sys.modules[name] = None
    from backend.lights import load_all as load_lights
    from backend.materials import load_all as load_materials
    load_materials()
    load_lights()
    from .measure import render
    from .scenes import cornell_box
    t_import = time.perf_counter() - t0
    if args.scene != "cornell":
        raise SystemExit(f"unknown probe scene {args.scene!r}")
    data = cornell_box(args.size, args.size, args.spp, 6)
    run = render(data, args.spp, 3, 1, "probe")
    loaded = sorted(m for m in sys.modules if m.startswith("backend.") and sys.modules[m] is not None)
    import hashlib
    print(json.dumps({"cpu": run.cpu, "wall": run.wall, "import": t_import, "modules": len(loaded),
                      "image_sha": hashlib.sha256(run.image.tobytes()).hexdigest()[:16]}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
