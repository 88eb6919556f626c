"""Run Blender-side test code in a fresh bpy subprocess and return what it measured.

Every bpy test file calls ``run_cases(module, [case, ...])``: one child process imports bpy,
loads the add-on from this checkout in development mode (a symlink named ``lamina`` to the
repository root, so imports are the same relative imports as in the installed extension), runs
each case function of ``tests/blender/cases/<module>.py`` on a fresh empty scene, and prints
their JSON results. Global bpy state therefore never leaks between test files or into the rest
of the suite, and a crash in Blender fails the tests instead of killing pytest.
"""
from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
MARK = "LAMINA-CASE-RESULT "

HAS_BPY = importlib.util.find_spec("bpy") is not None
requires_bpy = pytest.mark.skipif(not HAS_BPY, reason="the bpy module is not installed")


def backend_capabilities() -> dict:
    """Which material/light/world types the backend in this checkout can load (no bpy)."""
    sys.path.insert(0, str(ROOT)) if str(ROOT) not in sys.path else None
    from backend.lights import load_all as lights
    from backend.materials import load_all as materials
    light_types, world_types = lights()
    return {"materials": sorted(materials()), "lights": sorted(light_types), "worlds": sorted(world_types)}


def backend_renders(materials=("diffuse",), lights=(), worlds=()) -> bool:
    caps = backend_capabilities()
    return (all(m in caps["materials"] for m in materials) and all(l in caps["lights"] for l in lights)
            and all(w in caps["worlds"] for w in worlds))


def backend_supports_ies() -> bool:
    sys.path.insert(0, str(ROOT)) if str(ROOT) not in sys.path else None
    try:
        return importlib.util.find_spec("backend.ies.light") is not None
    except ModuleNotFoundError:
        return False


def run_cases(module: str, cases: list[str], *, tmp: Path, env: dict | None = None,
              timeout: float = 300, args: dict | None = None, dev_load: bool = True) -> dict:
    """Run case functions in one bpy process; returns {case: result or {"error": text}}.

    ``dev_load=False`` leaves loading the add-on to the cases (extension install tests);
    ``dev_load="extension"`` loads this checkout as an extension (``bl_ext.lamina_dev.lamina``,
    from a local repository holding a symlink), so extension-only APIs such as
    ``bpy.utils.extension_path_user`` work. Cases find the package name in
    ``os.environ["LAMINA_TEST_PACKAGE"]``."""
    dev = repo = None
    if dev_load == "extension":
        repo = Path(tempfile.mkdtemp(prefix="lamina-repo-", dir=tmp))
        (repo / "lamina").symlink_to(ROOT, target_is_directory=True)
    elif dev_load:
        dev = Path(tempfile.mkdtemp(prefix="lamina-dev-", dir=tmp))
        (dev / "lamina").symlink_to(ROOT, target_is_directory=True)
    payload = {"module": module, "cases": cases, "dev": str(dev) if dev else None, "tmp": str(tmp),
               "repo": str(repo) if repo else None, "args": args or {}}
    child_env = dict(os.environ)
    child_env.setdefault("BLENDER_USER_RESOURCES", str(Path(tmp) / "blender-user"))
    # One kernel cache for every Blender child of the test run (an installed extension would
    # otherwise compile into its own user folder: ~1.5 min per case module). test_extension
    # passes "" to test that folder.
    from backend.kernels.cache import user_cache_root
    child_env.setdefault("LAMINA_KERNEL_CACHE", str(user_cache_root()))
    child_env["PYTHONPATH"] = os.pathsep.join([str(HERE), str(ROOT), child_env.get("PYTHONPATH", "")])
    if env:
        child_env.update(env)
    proc = subprocess.Popen([sys.executable, str(HERE / "bpy_runner.py"), json.dumps(payload)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=child_env,
                            cwd=str(tmp), start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)          # the runner and anything it started
        stdout, stderr = proc.communicate()
        raise AssertionError(f"bpy cases {cases} timed out after {timeout} s:\n{stdout[-3000:]}\n{stderr[-3000:]}")
    results = None
    for line in stdout.splitlines():
        if line.startswith(MARK):
            results = json.loads(line[len(MARK):])
    if results is None:
        raise AssertionError(f"bpy runner failed (status {proc.returncode}):\n"
                             f"{stdout[-3000:]}\n{stderr[-3000:]}")
    results["_stdout"] = stdout
    results["_stderr"] = stderr
    return results


def result_of(results: dict, case: str):
    value = results[case]
    if isinstance(value, dict) and "error" in value and len(value) == 1:
        pytest.fail(f"{case} failed inside Blender:\n{value['error']}")
    return value
