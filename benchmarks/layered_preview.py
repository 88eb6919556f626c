"""Wall time of a material preview of a layered preset, as the Blender add-on starts it: a child
process ``python -m backend render`` on the preset thumbnail stage (backend/preset_thumbnails.py)
at 64 × 64 px, 16 samples per pixel, one worker, warm kernel cache — start-up (interpreter,
imports, loading the cached kernels, the scene and its BVH) included.

    python -m benchmarks.layered_preview [--preset reference-microflake-3layer] [--size 64]
                                         [--spp 16] [--repeat 5]

Prints every run's wall time and, from the renderer's own report, the render part.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def scene_file(folder: Path, preset: str, size: int, spp: int) -> Path:
    sys.path.insert(0, str(ROOT))
    from backend.preset_thumbnails import STAGE, absolute_textures, stage_scene
    from backend.presets import find_preset
    path = find_preset(preset)
    material = json.loads(path.read_text())["material"]
    data = stage_scene(absolute_textures(material, path.parent), size, spp)
    out = folder / "preview.json"
    out.write_text(json.dumps(data))
    return out


def run_once(scene: Path, folder: Path) -> float:
    cmd = [sys.executable, "-m", "backend", "render", str(scene), "-o", str(folder / "p.exr"),
           "--workers", "1", "--progress", "none"]
    t0 = time.perf_counter()
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        raise SystemExit(out.stderr)
    return wall


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="reference-microflake-3layer")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        scene = scene_file(folder, args.preset, args.size, args.spp)
        run_once(scene, folder)        # warms the kernel cache (and the OS file cache)
        walls = [run_once(scene, folder) for _ in range(args.repeat)]
    walls.sort()
    print(f"{args.preset} preview {args.size}x{args.size}, {args.spp} spp, one worker, warm cache "
          f"(load {os.getloadavg()[0]:.2f}): wall {', '.join(f'{w:.2f}' for w in walls)} s; "
          f"median {walls[len(walls) // 2]:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
