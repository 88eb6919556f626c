"""Wall time of a material preview of a layered preset, as the Blender add-on starts it: a child
process ``python -m backend render`` on the preset thumbnail stage (backend/preset_thumbnails.py)
at 64 × 64 px, 16 samples per pixel, one worker, warm kernel cache — start-up (interpreter,
imports, loading the cached kernels, the scene and its BVH) included.

    python -m benchmarks.layered_preview [--preset reference-microflake-3layer] [--size 64]
                                         [--spp 16] [--repeat 5] [--no-bytecode]

Warm caches means both: the kernel cache and Python's bytecode cache (``__pycache__``), as in an
installed add-on (its folder is writable; the first run writes them). The child processes write
their bytecode into a private folder (``PYTHONPYCACHEPREFIX``, the benchmark's temporary folder:
the work tree stays clean) even when ``PYTHONDONTWRITEBYTECODE`` is set in the environment (some
sandboxes set it: every run then compiles ~100 modules from source, +0.1 s; ``--no-bytecode``
measures that case).

Prints every run's wall time and, from the renderer's own report, the render part.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
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


def child_env(folder: Path, bytecode: bool) -> dict:
    env = dict(os.environ)
    if bytecode:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(folder / "pycache")
    else:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


def run_once(scene: Path, folder: Path, env: dict | None = None, root: Path = ROOT) -> tuple[float, float]:
    """(wall s, CPU s) of one preview process."""
    cmd = [sys.executable, "-m", "backend", "render", str(scene), "-o", str(folder / "p.exr"),
           "--workers", "1", "--progress", "none"]
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, cwd=root, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        raise SystemExit(out.stderr)
    return wall, (c1.ru_utime + c1.ru_stime) - (c0.ru_utime + c0.ru_stime)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="reference-microflake-3layer")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-bytecode", action="store_true", help="no bytecode cache (every module compiled from source)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        scene = scene_file(folder, args.preset, args.size, args.spp)
        env = child_env(folder, not args.no_bytecode)
        run_once(scene, folder, env)   # warms the kernel and bytecode caches (and the OS file cache)
        runs = [run_once(scene, folder, env) for _ in range(args.repeat)]
    walls = sorted(w for w, _ in runs)
    cpus = sorted(c for _, c in runs)
    what = "no bytecode cache" if args.no_bytecode else "warm bytecode cache"
    print(f"{args.preset} preview {args.size}x{args.size}, {args.spp} spp, one worker, warm kernel cache, {what} "
          f"(load {os.getloadavg()[0]:.2f}): wall {', '.join(f'{w:.2f}' for w in walls)} s; "
          f"median {walls[len(walls) // 2]:.2f} s; CPU median {cpus[len(cpus) // 2]:.2f} s "
          f"[{cpus[0]:.2f}–{cpus[-1]:.2f}]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
