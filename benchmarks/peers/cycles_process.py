"""The parent's handle on the bpy child (``cycles_child.py``): start, build, render, stop.

The child stays alive for the whole section, so Blender's start-up (importing bpy, about a
second) is paid once and reported separately; each render still syncs the scene and builds its
BVH (persistent data off), which is part of its CPU time. The child's CPU time never appears in
the parent's ``RUSAGE_CHILDREN`` while it runs, so it cannot leak into Lamina's measurements; it
reports its own per-render ``RUSAGE_SELF`` difference instead.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

CHILD = Path(__file__).resolve().parent / "cycles_child.py"
# Set by backend/__init__.py for Lamina's processes; Blender must not inherit them.
_LAMINA_ENV = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


class CyclesError(RuntimeError):
    pass


def bpy_available() -> str | None:
    """None if the bpy module can be imported by this Python, else why not."""
    out = subprocess.run([sys.executable, "-c", "import bpy; print(bpy.app.version_string)"],
                         capture_output=True, text=True, env=_child_env())
    if out.returncode != 0:
        return (out.stderr.strip().splitlines() or ["bpy not importable"])[-1]
    return None


def _child_env() -> dict:
    env = {k: v for k, v in os.environ.items() if k not in _LAMINA_ENV}
    env.setdefault("PYTHONHASHSEED", "0")
    return env


class CyclesProcess:
    def __init__(self, log_path: Path | None = None):
        self._log = open(log_path or os.devnull, "w", encoding="utf-8")   # noqa: SIM115 - closed in close()
        self.tmp = Path(tempfile.mkdtemp(prefix="lamina-peers-"))
        self.proc = subprocess.Popen([sys.executable, str(CHILD)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=self._log, text=True, env=_child_env(), cwd=str(self.tmp))
        self.hello = self._read()
        self.version = None

    def _read(self) -> dict:
        for line in self.proc.stdout:
            if line.startswith("REPLY "):
                reply = json.loads(line[6:])
                if reply.get("ok") is False:
                    raise CyclesError(f"Cycles child: {reply.get('error')}\n{reply.get('trace', '')}")
                return reply
            self._log.write(line)
        raise CyclesError(f"Cycles child exited (code {self.proc.wait()}); see its log")

    def _ask(self, **req) -> dict:
        self.proc.stdin.write(json.dumps(req) + "\n")
        self.proc.stdin.flush()
        return self._read()

    def build(self, job_json: Path, threads: int) -> dict:
        reply = self._ask(cmd="build", job=str(job_json), threads=threads)
        self.version = reply["info"].get("blender")
        return reply

    def render(self, spp: int, seed: int) -> tuple[np.ndarray, float, float]:
        """(image (H, W, 3) float64, CPU seconds, wall seconds) of one render."""
        out = self.tmp / "render.npy"
        reply = self._ask(cmd="render", spp=int(spp), seed=int(seed), out=str(out))
        img = np.load(out).astype(np.float64)
        out.unlink()
        return img, float(reply["cpu"]), float(reply["wall"])

    def close(self) -> None:
        try:
            if self.proc.poll() is None:
                self._ask(cmd="quit")
                self.proc.wait(timeout=30)
        except Exception:  # noqa: BLE001 - best effort; the child is ours, stop it by its id
            self.proc.kill()
            self.proc.wait()
        finally:
            self._log.close()
            for f in self.tmp.glob("*"):
                f.unlink()
            self.tmp.rmdir()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
