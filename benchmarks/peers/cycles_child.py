"""The Cycles side of the benchmark: a bpy process that builds scenes and renders on request.

Started by ``run.CyclesProcess`` as ``python benchmarks/peers/cycles_child.py`` (a script, not
``-m benchmarks...``, so that neither the backend nor its one-BLAS-thread environment is loaded
into Blender). Requests are JSON lines on stdin; each reply is one line on stdout starting with
``REPLY`` (Blender and Cycles print their own progress lines on stdout too):

    {"cmd": "build", "job": ".../job.json", "threads": 2}  → checks of the built scene, CPU time
    {"cmd": "render", "spp": 16, "seed": 3, "out": ".../x.npy"} → cpu, wall (the image in x.npy)
    {"cmd": "quit"}

CPU time is this process's own ``getrusage(RUSAGE_SELF)`` (user + system, every thread: Cycles
renders with threads of this process) around ``bpy.ops.render.render`` — scene sync, BVH build,
rendering and writing the EXR; reading the EXR back for the benchmark is not counted.
"""
from __future__ import annotations

import json
import os
import resource
import sys
import time
import traceback
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _read_exr(path: Path) -> np.ndarray:
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise RuntimeError(f"cannot read {path}: {oiio.geterror()}")
    spec = inp.spec()
    px = inp.read_image(0, 0, 0, 3, oiio.FLOAT)
    inp.close()
    return np.asarray(px, dtype=np.float32).reshape(spec.height, spec.width, 3)


def _reply(obj: dict) -> None:
    sys.stdout.write("REPLY " + json.dumps(obj) + "\n")
    sys.stdout.flush()


def main() -> int:
    t0, c0 = time.perf_counter(), _cpu()
    import to_cycles  # imports bpy
    _reply({"ready": True, "import_cpu": _cpu() - c0, "import_wall": time.perf_counter() - t0, "pid": os.getpid()})
    for line in sys.stdin:
        if not line.strip():
            continue
        req = json.loads(line)
        try:
            if req["cmd"] == "quit":
                _reply({"ok": True})
                return 0
            if req["cmd"] == "build":
                c0, t0 = _cpu(), time.perf_counter()
                info = to_cycles.build(Path(req["job"]), int(req["threads"]))
                _reply({"ok": True, "info": info, "cpu": _cpu() - c0, "wall": time.perf_counter() - t0})
            elif req["cmd"] == "render":
                exr = Path(req["out"]).with_suffix(".exr")
                c0, t0 = _cpu(), time.perf_counter()
                to_cycles.render(exr, req["spp"], req["seed"])
                cpu, wall = _cpu() - c0, time.perf_counter() - t0
                np.save(req["out"], _read_exr(exr))
                exr.unlink()
                _reply({"ok": True, "cpu": cpu, "wall": wall})
            else:
                _reply({"ok": False, "error": f"unknown command {req['cmd']!r}"})
        except Exception as exc:  # noqa: BLE001 - reported to the parent, which raises
            _reply({"ok": False, "error": f"{type(exc).__name__}: {exc}", "trace": traceback.format_exc()})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
