"""The add-on's session client (addon/engine/session_client.py, no bpy): generations and stale
frames, big updates through files, a crashed session reported, stop leaves no process."""
from __future__ import annotations

import copy
import importlib.util
import json
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from test_session import small_scene

from backend.session.frames import FrameWriter

_pkg = importlib.util.spec_from_file_location("lamina_engine_pkg", ROOT / "addon" / "engine" / "__init__.py",
                                              submodule_search_locations=[str(ROOT / "addon" / "engine")])
_module = importlib.util.module_from_spec(_pkg)
sys.modules["lamina_engine_pkg"] = _module
_pkg.loader.exec_module(_module)
from lamina_engine_pkg.session_client import (INLINE_LIMIT, SessionClient, read_frame_file,  # noqa: E402
                                              session_command)

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups + /proc (Linux)")


class FakeJob:
    """BackendJob's interface with scripted output."""

    def __init__(self):
        self.sent: list[dict] = []
        self.out: list[dict] = []
        self.running = True
        self.proc = type("P", (), {"pid": 0, "poll": lambda self: None})()

    def send(self, line):
        self.sent.append(json.loads(line))
        return True

    def poll(self, timeout=0.0):
        out, self.out = self.out, []
        return out

    def close_stdin(self):
        pass

    def kill_group(self):
        self.running = False

    def failure_message(self):
        return "?"


def test_only_frames_of_the_newest_generation_are_handed_out(tmp_path):
    job = FakeJob()
    c = SessionClient(["x"], tmp_path, job=job)
    writer = FrameWriter(tmp_path / "frames")
    img = np.full((2, 3, 4), 0.5, np.float32)
    assert c.send_scene(tmp_path / "scene.json") == 1
    path, n = writer.write(img, generation=1, spp=1, scale=1, final=False)
    job.out.append({"event": "frame", "generation": 1, "frame": n, "path": str(path)})
    c.poll()
    frame = c.take_frame()
    assert (frame.generation, frame.frame, frame.width, frame.height) == (1, 1, 3, 2)
    assert c.take_frame() is None                               # handed out once
    assert c.send_update({"camera": {"type": "x"}}) == 2
    # A frame of generation 1 still on its way arrives after the edit was sent: refused.
    path, n = writer.write(img, generation=1, spp=2, scale=1, final=False)
    job.out.append({"event": "frame", "generation": 1, "frame": n, "path": str(path)})
    c.poll()
    assert c.take_frame() is None and c.stale_frames == 1 and c.answered == 1
    # A file that holds an older generation than its event says is refused too.
    job.out.append({"event": "frame", "generation": 2, "frame": n, "path": str(path)})
    c.poll()
    assert c.take_frame() is None
    path, n = writer.write(img * 2, generation=2, spp=1, scale=4, final=False)
    job.out.append({"event": "frame", "generation": 2, "frame": n, "path": str(path)})
    c.poll()
    frame = c.take_frame()
    assert (frame.generation, frame.scale) == (2, 4) and c.answered == 2
    np.testing.assert_array_equal(frame.pixels, img * 2)
    # Errors about a superseded edit do not count; about the current one they do.
    c.send_update({"lights": []})
    job.out.append({"event": "error", "generation": 2, "message": "old", "fatal": False})
    job.out.append({"event": "error", "generation": 3, "message": "bad light", "fatal": False})
    c.poll()
    assert c.scene_error == "bad light" and c.answered == 3 and c.error is None
    assert [m["cmd"] for m in job.sent] == ["scene", "update", "update"]
    assert [m["generation"] for m in job.sent] == [1, 2, 3]


def test_big_updates_travel_through_a_file(tmp_path):
    job = FakeJob()
    c = SessionClient(["x"], tmp_path, job=job)
    c.send_scene(tmp_path / "scene.json")
    objects = [{"name": f"o{i}", "mesh": "m", "to_world": np.eye(4).tolist()} for i in range(400)]
    assert len(json.dumps(objects)) > INLINE_LIMIT
    c.send_update({"objects": objects})
    message = job.sent[-1]
    assert "changes" not in message
    assert json.loads(Path(message["changes_file"]).read_text()) == {"objects": objects}


def test_unreadable_frame_files_are_none(tmp_path):
    assert read_frame_file(tmp_path / "missing.bin") is None
    (tmp_path / "short.bin").write_bytes(b"LAMFRAME")
    assert read_frame_file(tmp_path / "short.bin") is None


def _env():
    return dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")


def _poll_until(c, test, timeout=120.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        c.poll()
        if test(c):
            return
        time.sleep(0.01)
    raise AssertionError(f"timed out: error={c.error} scene_error={c.scene_error} {c.job.stderr_text()[-2000:]}")


def _group_alive(pgid):
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@linux_only
def test_real_session_frames_edit_and_stop(tmp_path):
    data = small_scene(width=48, height=32)
    (tmp_path / "scene.json").write_text(json.dumps(data))
    c = SessionClient(session_command(sys.executable, tmp_path / "frames", samples=2, workers=1), tmp_path,
                      env=_env())
    try:
        c.send_scene(tmp_path / "scene.json")
        _poll_until(c, lambda c: c.idle)
        frame = c.take_frame()
        assert frame.generation == 1 and frame.final and frame.spp == 2
        cam = copy.deepcopy(data["camera"])
        cam["to_world"][0][3] = 0.3
        c.send_update({"camera": cam})
        _poll_until(c, lambda c: c.idle)
        frame = c.take_frame()
        assert frame.generation == 2 and c.last_updated["rebuilt"] == ["camera"]
        pid = c.pid
    finally:
        t0 = time.monotonic()
        c.stop()
    assert time.monotonic() - t0 < 2.0
    assert not _group_alive(pid) and c.job.returncode == 0


@linux_only
def test_a_crashed_session_is_reported_in_one_line(tmp_path):
    data = small_scene(width=48, height=32)
    (tmp_path / "scene.json").write_text(json.dumps(data))
    c = SessionClient(session_command(sys.executable, tmp_path / "frames", samples=0, workers=1), tmp_path,
                      env=_env())
    try:
        c.send_scene(tmp_path / "scene.json")
        _poll_until(c, lambda c: c.answered >= 1)
        os.kill(c.pid, signal.SIGKILL)
        _poll_until(c, lambda c: c.error is not None, timeout=10)
        assert c.error == "the viewport renderer process ended unexpectedly (signal 9)"
        assert "\n" not in c.error
    finally:
        c.stop()
    assert not _group_alive(c.pid)
