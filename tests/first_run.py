"""The first run on a cold kernel cache, done once per test session.

A fresh checkout (CI) starts with an empty kernel cache, so some test has to pay the cold compile
(about a minute). test_kernels_core's first-run test also needs a cold compile, of its own, to
see the "compiling render kernels" message: done in a private folder, that was a second
compile of the same kernels. So when that test is selected and the session's shared cache is
cold, ``record_if_cold`` (called from conftest before the first test) runs the test's first
render into the shared cache and keeps its output: the compile every later test needs is the
one the first-run test examines. With a warm cache the test compiles into a folder of its own
as before (nothing recorded).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from render_util import front_perspective, scene

ROOT = Path(__file__).resolve().parent.parent
TEST_ID = "test_kernels_core.py::test_first_run_compiles_once_and_says_so"

# Filled by record_if_cold: {"first": CompletedProcess, "env": dict, "root": Path, "scene": Path}
RECORD: dict = {}
_FOLDERS: list[Path] = []


def mixed_scene(spp=12):
    """A small scene with diffuse, rough conductor and rough dielectric surfaces, a point light
    and a constant environment (most analytic kernels in one render)."""
    materials = {"white": {"type": "diffuse", "color": [0.7, 0.7, 0.7]},
                 "gold": {"type": "conductor", "metal": "Au", "roughness": 0.3},
                 "glass": {"type": "dielectric", "ior": 1.5, "roughness": 0.2}}
    meshes = {"floor": {"shape": "rectangle", "size": [6, 6]},
              "ball": {"shape": "sphere", "radius": 0.5, "segments": 24}}
    objects = [{"name": "floor", "mesh": "floor", "materials": ["white"]},
               {"name": "a", "mesh": "ball", "materials": ["gold"],
                "to_world": [[1, 0, 0, -0.6], [0, 1, 0, 0], [0, 0, 1, 0.5], [0, 0, 0, 1]]},
               {"name": "b", "mesh": "ball", "materials": ["glass"],
                "to_world": [[1, 0, 0, 0.6], [0, 1, 0, 0], [0, 0, 1, 0.5], [0, 0, 0, 1]]}]
    lights = [{"type": "point", "to_world": [[1, 0, 0, 0.5], [0, 1, 0, -1], [0, 0, 1, 3], [0, 0, 0, 1]],
               "power": 200.0}]
    cam = front_perspective(5.0, 0.3, 1.5)
    cam["to_world"][2][3] = 0.6
    return scene(24, 16, cam, materials, meshes, objects, lights,
                 world={"type": "constant", "color": [0.2, 0.25, 0.3]},
                 render={"spp": spp, "max_bounces": 5, "rr_depth": 2, "seed": 3})


def cli(args, env=None, cwd=None):
    return subprocess.run([sys.executable, "-m", "backend", *args], capture_output=True, text=True,
                          env=env, cwd=cwd or ROOT)


def first_run_env(cache_root: Path) -> dict:
    env = dict(os.environ, LAMINA_KERNEL_CACHE=str(cache_root), PYTHONPATH=str(ROOT))
    env.pop("LAMINA_SERIAL_COMPILE", None)
    return env


def first_render(folder: Path, cache_root: Path):
    """(the first render's process, its environment, the scene file): the test's first run,
    with Numba's cache log on stdout (which kernels were compiled, which loaded)."""
    path = folder / "s.json"
    path.write_text(json.dumps(mixed_scene(spp=1)))
    env = first_run_env(cache_root)
    proc = cli(["render", str(path), "-o", str(folder / "a.exr"), "--workers", "1"],
               dict(env, NUMBA_DEBUG_CACHE="1"))
    return proc, env, path


def record_if_cold(items) -> None:
    """Run the first render into the session's shared cache if the first-run test is selected
    and that cache is cold (see the module docstring)."""
    if not any(item.nodeid.endswith(TEST_ID) for item in items):
        return
    from backend.kernels import cache
    root = cache.user_cache_root()
    if (root / cache.source_key() / "warm").exists():
        return
    folder = Path(tempfile.mkdtemp(prefix="pytest-first-run-"))
    _FOLDERS.append(folder)
    print(f"\n[tests] cold kernel cache {root}: compiling it with the first-run test's render", flush=True)
    proc, env, path = first_render(folder, root)
    RECORD.update(first=proc, env=env, root=root, scene=path, folder=folder)
    # The cold-compile time in the test log (issue 15 asks for it; the test checks the line).
    said = [line for line in proc.stderr.splitlines() if "compiled render kernels in" in line]
    print(f"[tests] {said[-1].strip() if said else 'the first render printed no compile time'}", flush=True)


def clean_up() -> None:
    for folder in _FOLDERS:
        shutil.rmtree(folder, ignore_errors=True)
