"""One timed render in a fresh interpreter, for the "features cost nothing" A/B (sections.overhead).

    python -m benchmarks.probe --scene cornell --size 96 --spp 32 [--block]

The timed render follows an untimed warm-up render in the same process. ``--block`` makes the optional feature modules unimportable before the backend is imported
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
FEATURE_MODULES = ["backend.layered.material", "backend.layered.bsdf",
                   "backend.layered.medium", "backend.layered.phase", "backend.ies.light", "backend.ies.profile",
                   "backend.lights.environment", "backend.lights.point", "backend.lights.spot", "backend.lights.sun"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="cornell")
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--block", action="store_true")
    ap.add_argument("--count-calls", action="store_true",
                    help="count Python function calls during the render (deterministic) instead of timing")
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
    if args.count_calls:
        # Profile the render only (the scene load of B makes failed import attempts of the
        # blocked modules, which is import machinery, not rendering).
        import cProfile
        import copy
        import pstats

        from backend.render import Renderer, RenderOptions
        from backend.scene.loader import load_scene_data
        scene = load_scene_data(copy.deepcopy(data), "<probe>")
        opts = RenderOptions(spp=args.spp, seed=3, workers=1)
        opts.apply(scene)
        renderer = Renderer(scene, (data, "<probe>", None), opts)
        prof = cProfile.Profile()
        prof.enable()
        renderer.run()
        prof.disable()
        st = pstats.Stats(prof).stats
        calls = sum(v[1] for v in st.values())
        backend_calls = sum(v[1] for k, v in st.items() if "/backend/" in k[0].replace("\\", "/"))
        print(json.dumps({"calls": calls, "backend_calls": backend_calls}))
        return 0
    # The first render of a process pays one-time costs (lazy imports, embree start-up, NumPy's
    # first calls): a warm-up render, then the timed one.
    render(data, args.spp, 3, 1, "probe")
    run = render(data, args.spp, 3, 1, "probe")
    loaded = sorted(m for m in sys.modules if m.startswith("backend.") and sys.modules[m] is not None)
    import hashlib
    print(json.dumps({"cpu": run.cpu, "wall": run.wall, "import": t_import, "modules": len(loaded),
                      "image_sha": hashlib.sha256(run.image.tobytes()).hexdigest()[:16]}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
