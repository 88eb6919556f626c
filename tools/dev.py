#!/usr/bin/env python3
"""Lamina developer entry point: the README's two commands and a few helpers.

    python3.11 tools/dev.py demo     render the demo scene to out/demo.exr and out/demo.png
    python3.11 tools/dev.py test     run the whole test suite (pytest) under Python 3.11 (Blender 4.2-5.0)
                             and, alongside it, the Blender tests under Python 3.13 with the newest
                             bpy (Blender 5.1+, NumPy 2.x) in .venv-313; --only-311 / --only-313
    python3.11 tools/dev.py bench    run the benchmark report (benchmarks/)
    python3.11 tools/dev.py build    build the Blender extension zips (one per platform and Python) into build/dist/
    python3.11 tools/dev.py showcase render the showcase scene to out/showcase.exr and out/showcase.png
                             (--blend: render showcase/showcase.blend in bpy to out/showcase_blend.png)
    python3.11 tools/dev.py thumbnails  render the preset thumbnails and the gallery (docs/presets.md)

Each command first creates or updates a local virtual environment (.venv) with the pinned
requirements, so nothing but python3.11 needs to be installed. ``test`` also creates .venv-313
(requirements-313.txt) when a Python 3.13 is found (on PATH, through pyenv, or named by
LAMINA_PYTHON313); without one that part is skipped with one line saying so. The two environments
are installed at the same time, and a few 3.11 test files run after the 3.13 tests in the second
lane (SECOND_LANE_311), so both lanes end together. The environment is only
re-installed when a requirements file changes (a hash of them is stored inside .venv).
Only the standard library is used here: this file runs before anything is installed.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv"
STAMP = VENV / ".lamina-requirements"
VENV_313 = ROOT / ".venv-313"
REQUIREMENTS_313 = ROOT / "requirements-313.txt"


def venv_python(venv: Path = VENV) -> Path:
    return venv / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def requirements_for(kind: str) -> Path:
    return ROOT / ("requirements-dev.txt" if kind == "dev" else "requirements.txt")


def wanted_stamp(kind: str) -> str:
    digest = hashlib.sha256()
    for name in ("requirements.txt", "requirements-dev.txt", "requirements-denoise.txt"):
        digest.update((ROOT / name).read_bytes())
    return f"{kind}:{digest.hexdigest()}"


def ensure_venv(kind: str) -> Path:
    """Create/update .venv. A 'dev' environment also satisfies 'runtime'."""
    if sys.version_info[:2] != (3, 11):
        print(f"note: running under Python {sys.version.split()[0]}; Lamina is pinned for 3.11",
              file=sys.stderr)
    have = STAMP.read_text().strip() if STAMP.exists() else ""
    if have == wanted_stamp(kind) or (kind == "runtime" and have == wanted_stamp("dev")):
        return venv_python()
    if not venv_python().exists():
        print(f"[lamina] creating virtual environment in {VENV}", flush=True)
        venv.EnvBuilder(with_pip=True, clear=False).create(VENV)
    py = str(venv_python())
    print(f"[lamina] installing {requirements_for(kind).name} into .venv (first run only)", flush=True)
    subprocess.check_call([py, "-m", "pip", "install", "--disable-pip-version-check", "-q",
                           "-r", str(requirements_for(kind))])
    STAMP.write_text(wanted_stamp(kind) + "\n")
    return venv_python()


def run(cmd: list[str], extra_env: dict | None = None) -> int:
    env = dict(os.environ)
    env.setdefault("PYTHONHASHSEED", "0")
    env.update(extra_env or {})
    return subprocess.call(cmd, cwd=ROOT, env=env)


def _works(cmd: list[str], env: dict | None = None) -> bool:
    try:
        out = subprocess.run([*cmd, "-c", "import sys, venv; print(sys.version_info[:2] == (3, 13))"],
                             capture_output=True, text=True, timeout=60, env=env)
    except (OSError, subprocess.SubprocessError):
        return False
    return out.returncode == 0 and out.stdout.strip() == "True"


def find_python313() -> tuple[list[str], dict] | None:
    """A Python 3.13 interpreter (command, environment): $LAMINA_PYTHON313, python3.13 on PATH,
    or a pyenv-installed 3.13 (pyenv's shim needs PYENV_VERSION naming it)."""
    named = os.environ.get("LAMINA_PYTHON313")
    if named:
        return ([named], {}) if _works([named]) else None
    if _works(["python3.13"]):
        return ["python3.13"], {}
    try:
        versions = subprocess.run(["pyenv", "versions", "--bare"], capture_output=True, text=True,
                                  timeout=60).stdout.split()
    except (OSError, subprocess.SubprocessError):
        return None
    for version in sorted((v for v in versions if v.startswith("3.13")), reverse=True):
        env = dict(os.environ, PYENV_VERSION=version)
        if _works(["python3.13"], env):
            return ["python3.13"], {"PYENV_VERSION": version}
    return None


def ensure_venv_313(found: tuple[list[str], dict]) -> Path:
    """Create/update .venv-313 from requirements-313.txt (a hash of it is stored inside)."""
    stamp = VENV_313 / ".lamina-requirements"
    wanted = "313:" + hashlib.sha256(REQUIREMENTS_313.read_bytes()).hexdigest()
    py = venv_python(VENV_313)
    if stamp.exists() and stamp.read_text().strip() == wanted and py.exists():
        return py
    cmd, extra = found
    if not py.exists():
        print(f"[lamina] creating virtual environment in {VENV_313} (Python 3.13)", flush=True)
        subprocess.check_call([*cmd, "-m", "venv", str(VENV_313)], env=dict(os.environ, **extra))
    print(f"[lamina] installing {REQUIREMENTS_313.name} into .venv-313 (first run only)", flush=True)
    subprocess.check_call([str(py), "-m", "pip", "install", "--disable-pip-version-check", "-q",
                           "-r", str(REQUIREMENTS_313)])
    stamp.write_text(wanted + "\n")
    return py


# Test files of the 3.11 run that go to the second lane, after the Python 3.13 tests, when those
# run alongside (see SecondLane): ~130 s of the 3.11 run, so the two lanes end at about the same
# time instead of the 3.11 run going on alone on one core (measured in a fresh-clone CI run:
# 3.11 run 1017 s, 3.13 run 670 s, both in parallel).
SECOND_LANE_311 = ["tests/blender/test_extension.py", "tests/blender/test_blender_presets.py"]


class SecondLane:
    """The second of the two test lanes, in a background thread: create .venv-313 (while the
    foreground creates .venv), run the Blender tests under Python 3.13 with the newest bpy
    (pytest -m blender), then, once .venv is ready, the 3.11 tests in ``tail``. Each lane keeps
    about one of two cores busy (measured: 1.05 cores on average), so together they take the
    longer lane's time instead of the sum. Output goes to log files, printed after the
    foreground run."""

    def __init__(self, found, rest: list[str], tail: list[str]):
        import tempfile
        import threading
        self.rest, self.tail, self.found = rest, tail, found
        self.status = 0
        self.reports: list[tuple[str, Path | str]] = []
        # not "lamina-": tests look for leaked Lamina temp names
        self.folder = Path(tempfile.mkdtemp(prefix="pytest-lanes-"))
        self.venv_311 = threading.Event()
        self.python_311: Path | None = None
        self.thread = threading.Thread(target=self._work, name="second test lane", daemon=True)
        self.thread.start()

    def venv_311_ready(self, python: Path | None) -> None:
        self.python_311 = python
        self.venv_311.set()

    def _pytest(self, py, args: list[str], name: str, title: str) -> int:
        log = self.folder / f"{name}.log"
        env = dict(os.environ, PYTHONHASHSEED=os.environ.get("PYTHONHASHSEED", "0"))
        # A base temp folder of its own: two pytest sessions must not clean up each other's folders.
        with log.open("w") as out:
            status = subprocess.call([str(py), "-m", "pytest", "-q", "--basetemp", str(self.folder / name),
                                      *args], cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT)
        self.reports.append((title, log))
        return 0 if status == 5 else status          # 5: the selection holds no test

    def _work(self) -> None:
        try:
            py = ensure_venv_313(self.found)
        except (OSError, subprocess.CalledProcessError) as exc:
            self.reports.append(("Python 3.13 environment", f"could not be installed: {exc}\n"))
            self.status = 1
        else:
            print("[lamina] Blender tests under Python 3.13 (bpy 5.3.0, NumPy 2.x), .venv-313: started "
                  "alongside (their output follows the 3.11 suite's)", flush=True)
            paths = [] if any(arg.startswith("tests") for arg in self.rest) else ["tests"]
            self.status = self._pytest(py, ["-m", "blender", *paths, *self.rest], "py313",
                                       "Blender tests under Python 3.13 (bpy 5.3.0, NumPy 2.x)")
        if self.tail:
            self.venv_311.wait()
            if self.python_311 is None:
                return
            status = self._pytest(self.python_311, [*self.tail, *self.rest], "py311-tail",
                                  f"Python 3.11 tests run in the second lane ({', '.join(self.tail)})")
            self.status = self.status or status

    def finish(self) -> int:
        self.thread.join()
        for title, log in self.reports:
            print(f"[lamina] {title}:", flush=True)
            sys.stdout.write(log.read_text(errors="replace") if isinstance(log, Path) else log)
            sys.stdout.flush()
        return self.status


def main(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0
    command, rest = argv[0], argv[1:]
    if command == "demo":
        py = ensure_venv("runtime")
        (ROOT / "out").mkdir(exist_ok=True)
        return run([str(py), "-m", "backend", "render", "demo/demo.json",
                    "-o", "out/demo.exr", "--png", "out/demo.png", *rest])
    if command == "showcase" and "--blend" in rest:
        py = ensure_venv("dev")                      # the bpy module renders the .blend
        (ROOT / "out").mkdir(exist_ok=True)
        rest = [a for a in rest if a != "--blend"]
        return run([str(py), "tools/render_blend.py", "showcase/showcase.blend",
                    "-o", "out/showcase_blend.png", *rest])
    if command == "showcase":
        py = ensure_venv("runtime")
        (ROOT / "out").mkdir(exist_ok=True)
        return run([str(py), "-m", "backend", "render", "showcase/showcase.json",
                    "-o", "out/showcase.exr", "--png", "out/showcase.png", *rest])
    if command == "thumbnails":
        py = ensure_venv("runtime")
        return run([str(py), "-m", "backend", "presets", "thumbnails", *rest])
    if command == "test":
        only_311, only_313 = "--only-311" in rest, "--only-313" in rest
        rest = [a for a in rest if a not in ("--only-311", "--only-313")]
        named = any(arg.startswith("tests") for arg in rest)
        found = None if only_311 else find_python313()
        if found is None and not only_311:
            print("[lamina] skipped the Blender 5.1+ tests: no Python 3.13 found "
                  "(install python3.13, or set LAMINA_PYTHON313)", flush=True)
        # The second lane takes over part of the 3.11 run when it runs the whole suite.
        tail = SECOND_LANE_311 if (found is not None and not only_313 and not named) else []
        lane = SecondLane(found, rest, tail) if found is not None else None
        status = 0
        if not only_313:
            try:
                py = ensure_venv("dev")
            except BaseException:
                if lane is not None:
                    lane.venv_311_ready(None)
                raise
            if lane is not None:
                lane.venv_311_ready(py)
            # Always name the tests folder, so pytest finds tests/pytest.ini (see the comment there).
            paths = [] if named else ["tests"]
            skip = [arg for path in tail for arg in ("--ignore", path)]
            status = run([str(py), "-m", "pytest", "-q", *paths, *skip, *rest])
        elif lane is not None:
            lane.venv_311_ready(None)
        status_2 = lane.finish() if lane is not None else 0
        return status or status_2
    if command == "bench":
        py = ensure_venv("dev")
        return run([str(py), "-m", "benchmarks", *rest])
    if command == "build":
        py = ensure_venv("dev")
        return run([str(py), "tools/build_extension.py", *rest])
    print(f"unknown command {command!r}\n{__doc__}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
