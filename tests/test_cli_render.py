"""The render CLI end to end: outputs, JSON progress protocol, partial results, clean stop."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from backend.imageio import read_exr
from conftest import ROOT
from render_util import front_perspective, scene


def furnace(spp, size=32):
    return scene(size, size, front_perspective(4.0, 0.3), {"m": {"type": "diffuse", "color": 0.8}},
                 {"ball": {"shape": "sphere", "radius": 1.0, "segments": 32}}, [{"mesh": "ball", "materials": ["m"]}],
                 world={"type": "constant", "color": [0.5, 0.5, 0.5], "strength": 1.0},
                 render={"spp": spp, "max_bounces": 4, "seed": 1})


def write_scene(tmp_path: Path, data: dict) -> Path:
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(data))
    return path


def test_render_writes_exr_passes_png_and_json_progress(tmp_path):
    path = write_scene(tmp_path, furnace(8))
    out = tmp_path / "out" / "image.exr"
    partial = tmp_path / "partial.npy"
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(path), "-o", str(out),
                           "--png", str(tmp_path / "preview.png"), "--workers", "2", "--progress", "json",
                           "--partial", str(partial), "--partial-interval", "0"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    events = [json.loads(line) for line in proc.stdout.splitlines()]
    kinds = [e["event"] for e in events]
    assert kinds[0] == "start" and kinds[-1] == "done"
    assert "progress" in kinds and "partial" in kinds
    fractions = [e["fraction"] for e in events if e["event"] == "progress"]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert events[-1]["spp"] == 8 and events[-1]["path"] == str(out.resolve())
    pixels, names = read_exr(out)
    assert pixels.shape == (32, 32, len(names))
    for channel in ("R", "G", "B", "A", "albedo.R", "normal.X", "variance.R", "samples.Y"):
        assert channel in names
    assert np.all(np.isfinite(pixels))
    assert np.all(pixels[:, :, names.index("samples.Y")] == 8)
    assert (tmp_path / "preview.png").stat().st_size > 0
    final = np.load(partial)
    assert final.shape == (32, 32, 4)
    assert np.allclose(final[:, :, :3], pixels[:, :, :3], rtol=1e-6, atol=1e-7)
    aovs = np.load(partial.with_suffix(".aovs.npy"))
    assert aovs.shape == (32, 32, 6)


def _processes_with_marker(marker: str) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if marker.encode() in (entry / "environ").read_bytes():
                found.append(int(entry.name))
        except OSError:
            continue
    return found


def test_sigterm_stops_cleanly_writes_result_and_leaves_no_workers(tmp_path):
    path = write_scene(tmp_path, furnace(100000, size=48))
    out = tmp_path / "image.exr"
    marker = f"LAMINA_TEST_MARKER_{os.getpid()}_{time.time_ns()}"
    env = dict(os.environ, LAMINA_TEST_MARKER=marker)
    proc = subprocess.Popen([sys.executable, "-m", "backend", "render", str(path), "-o", str(out),
                             "--workers", "2", "--progress", "json"], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Wait for the first progress line: workers are running.
    while True:
        line = proc.stdout.readline()
        assert line, proc.stderr.read()
        if json.loads(line)["event"] == "progress":
            break
    t0 = time.perf_counter()
    proc.send_signal(signal.SIGTERM)
    rest, err = proc.communicate(timeout=60)
    stop_time = time.perf_counter() - t0
    assert proc.returncode == 130, err
    assert stop_time < 20
    done = json.loads(rest.splitlines()[-1])
    assert done["event"] == "done" and done["interrupted"] is True
    pixels, names = read_exr(out)
    samples = pixels[:, :, names.index("samples.Y")]
    assert samples.max() > 0 and samples.max() < 100000
    assert np.all(np.isfinite(pixels))
    time.sleep(0.5)
    assert _processes_with_marker(marker) == []
