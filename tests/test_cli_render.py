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


def test_unwritable_outputs_fail_before_rendering(tmp_path, monkeypatch, capsys):
    """A bad output path is reported at once (exit 2, one line, no traceback), not after the
    render: the folder of each output must be creatable and writable and the preview's format
    known."""
    from backend import cli, render
    path = write_scene(tmp_path, furnace(1, size=8))
    blocker = tmp_path / "file.txt"
    blocker.write_text("a file, not a folder")
    started = []
    monkeypatch.setattr(render.Renderer, "run", lambda self: started.append(1) or 1 / 0)
    cases = {
        ("-o", str(blocker / "sub" / "o.exr")): f"cannot write {blocker / 'sub' / 'o.exr'}: cannot create the folder",
        ("-o", str(tmp_path / "o.exr"), "--png", str(blocker / "p.png")): f"cannot write {blocker / 'p.png'}",
        ("-o", str(tmp_path / "o.exr"), "--png", str(tmp_path / "p.xyz")): "OpenImageIO cannot write '.xyz' files",
        ("-o", str(tmp_path / "o.exr"), "--png", str(tmp_path)): "is a folder; give a file name",
        ("-o", str(tmp_path / "o.exr"), "--partial", str(blocker / "p.npy")): f"cannot write {blocker / 'p.npy'}",
    }
    for args, message in cases.items():
        code = cli.main(["render", str(path), *args, "--progress", "none"])
        err = capsys.readouterr().err
        assert code == 2 and message in err and "Traceback" not in err, (args, err)
    assert not started                                   # no render began
    assert not list(tmp_path.glob(".o.*")) and not (tmp_path / "o.exr").exists()   # no scratch files left


def test_a_render_whose_output_cannot_be_written_at_the_end_is_rescued(tmp_path, monkeypatch, capsys):
    """If writing fails after the render (disk full, folder removed meanwhile), the image goes to
    the temporary folder and the error says where: the render is not lost."""
    import tempfile
    from backend import cli, imageio
    path = write_scene(tmp_path, furnace(2, size=8))
    out = tmp_path / "out" / "o.exr"
    real = imageio.write_exr
    rescue_dir = tmp_path / "tmpdir"
    rescue_dir.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(rescue_dir))

    def full_disk(target, layers, half=False):
        if Path(target) == out:
            raise OSError(28, "No space left on device")
        return real(target, layers, half)

    monkeypatch.setattr(imageio, "write_exr", full_disk)
    code = cli.main(["render", str(path), "-o", str(out), "--progress", "none", "--workers", "1"])
    err = capsys.readouterr().err
    (rescued,) = rescue_dir.glob("lamina-rescued-o-*.exr")
    assert code == 2 and "No space left on device" in err and f"saved to {rescued} instead" in err, err
    pixels, names = read_exr(rescued)
    assert pixels.shape == (8, 8, len(names)) and np.all(pixels[:, :, names.index("samples.Y")] == 2)


def test_out_of_range_options_are_refused_with_the_allowed_range(tmp_path, capsys):
    """Options take the scene format's ranges: a negative time limit rendered 0 spp (a black
    image) and a NaN noise target was silently ignored before."""
    import pytest
    from backend import cli
    path = write_scene(tmp_path, furnace(1, size=8))
    for option, value, message in [("--time-limit", "-1", "expected a number >= 0"),
                                   ("--noise-target", "nan", "expected a number in [0, 1]"),
                                   ("--noise-target", "1.5", "expected a number in [0, 1]"),
                                   ("--partial-interval", "-5", "expected a number >= 0"),
                                   ("--resolution", "70000x10", "(1 to 65536 each)"),
                                   ("--spp", "0", "expected an integer in [1, 16777216]"),
                                   ("--spp", str(10 ** 15), "expected an integer in [1, 16777216]"),
                                   ("--spp", "9" * 5000, "expected an integer in [1, 16777216]"),
                                   ("--min-spp", str(1 << 25), "expected an integer in [1, 16777216]"),
                                   ("--max-bounces", "1025", "expected an integer in [0, 1024]"),
                                   ("--workers", "65", "expected an integer in [1, 64]"),
                                   ("--seed", "-1", "expected an integer in [0, 9223372036854775807]")]:
        with pytest.raises(SystemExit) as info:
            cli.main(["render", str(path), "-o", str(tmp_path / "o.exr"), option, value])
        err = capsys.readouterr().err
        assert info.value.code == 2 and message in err and "Traceback" not in err, (option, err)
    assert not (tmp_path / "o.exr").exists()
