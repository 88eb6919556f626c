#!/usr/bin/env python3
"""Lamina developer entry point: the README's two commands and a few helpers.

    python3.11 tools/dev.py demo     render the demo scene to out/demo.exr and out/demo.png
    python3.11 tools/dev.py test     run the whole test suite (pytest)
    python3.11 tools/dev.py bench    run the benchmark report (benchmarks/)
    python3.11 tools/dev.py build    build the Blender extension zip into build/
    python3.11 tools/dev.py showcase render the showcase scene to out/showcase.exr and out/showcase.png
    python3.11 tools/dev.py thumbnails  render the preset thumbnails and the gallery (docs/presets.md)

Each command first creates or updates a local virtual environment (.venv) with the pinned
requirements, so nothing but python3.11 needs to be installed. The environment is only
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


def venv_python() -> Path:
    return VENV / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def requirements_for(kind: str) -> Path:
    return ROOT / ("requirements-dev.txt" if kind == "dev" else "requirements.txt")


def wanted_stamp(kind: str) -> str:
    digest = hashlib.sha256()
    for name in ("requirements.txt", "requirements-dev.txt"):
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


def run(cmd: list[str]) -> int:
    env = dict(os.environ)
    env.setdefault("PYTHONHASHSEED", "0")
    return subprocess.call(cmd, cwd=ROOT, env=env)


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
    if command == "showcase":
        py = ensure_venv("runtime")
        (ROOT / "out").mkdir(exist_ok=True)
        return run([str(py), "-m", "backend", "render", "showcase/showcase.json",
                    "-o", "out/showcase.exr", "--png", "out/showcase.png", *rest])
    if command == "thumbnails":
        py = ensure_venv("runtime")
        return run([str(py), "-m", "backend", "presets", "thumbnails", *rest])
    if command == "test":
        py = ensure_venv("dev")
        return run([str(py), "-m", "pytest", "-q", *rest])
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
