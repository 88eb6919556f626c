"""The renderer session (``python -m backend session``, docs/session.md), end to end and headless:
start, every kind of edit, accumulation restart, stale frames, coalescing, idle CPU, errors, stop."""
from __future__ import annotations

import copy
import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from render_util import IDENTITY, front_perspective, render, scene

from backend.session.frames import FrameWriter, read_frame
from backend.session.loop import LEVEL_PIXELS, Session, level_scales
from backend.session.protocol import END, ProtocolError, parse_command

LINUX = sys.platform.startswith("linux")


def quad(z=0.0, s=3.0):
    return {"positions": [[-s, -s, z], [s, -s, z], [s, s, z], [-s, s, z]], "indices": [[0, 1, 2], [0, 2, 3]]}


def small_scene(width=160, height=120, spp=4) -> dict:
    cam = front_perspective(distance=6.0, half_width=0.4, aspect=width / height)
    cam["to_world"][2][3] = 1.0
    box = {"positions": [[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0],
                         [-0.5, -0.5, 1], [0.5, -0.5, 1], [0.5, 0.5, 1], [-0.5, 0.5, 1]],
           "indices": [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                       [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]}
    return scene(width, height, cam,
                 {"floor": {"type": "diffuse", "color": [0.5, 0.5, 0.5]},
                  "paint": {"type": "diffuse", "color": [0.7, 0.3, 0.2]}},
                 {"floor": quad(), "box": box},
                 [{"name": "floor", "mesh": "floor", "materials": ["floor"]},
                  {"name": "box", "mesh": "box", "materials": ["paint"], "to_world": IDENTITY}],
                 lights=[{"type": "point", "to_world": [[1, 0, 0, 1], [0, 1, 0, -2], [0, 0, 1, 3], [0, 0, 0, 1]],
                          "power": 300.0}],
                 world={"type": "constant", "color": [0.2, 0.2, 0.2]},
                 render={"spp": spp, "max_bounces": 3, "seed": 5})


class SessionProcess:
    """A session child process; its stdout is read by a thread into a queue (test code only)."""

    def __init__(self, tmp: Path, samples=4, workers=1, extra=()):
        env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
        self.frames = tmp / "frames"
        self.proc = subprocess.Popen([sys.executable, "-m", "backend", "session", "--frames", str(self.frames),
                                      "--samples", str(samples), "--workers", str(workers), *extra],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, cwd=str(ROOT), env=env)
        self.events: queue.Queue = queue.Queue()
        self.log: list[dict] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            self.events.put(json.loads(line))
        self.events.put(None)

    def send(self, **message):
        self.proc.stdin.write(json.dumps(message) + "\n")
        self.proc.stdin.flush()

    def until(self, test, timeout=120.0) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"timed out; last events {self.log[-5:]}")
            try:
                event = self.events.get(timeout=left)
            except queue.Empty:
                continue
            if event is None:
                raise AssertionError(f"session ended: {self.proc.wait()} {self.proc.stderr.read()[-2000:]}; "
                                     f"last events {self.log[-5:]}")
            self.log.append(event)
            if test(event):
                return event

    def since(self, index: int) -> list[dict]:
        return self.log[index:]

    def close(self):
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()


@pytest.fixture
def session(tmp_path):
    s = SessionProcess(tmp_path)
    yield s
    s.close()


def _idle(g):
    return lambda e: e["event"] == "idle" and e["generation"] == g


def _start(s, tmp_path, data, g=1):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(data))
    s.until(lambda e: e["event"] == "ready")
    s.send(cmd="scene", generation=g, path=str(path))
    return s.until(_idle(g))


def _frames(events, g=None):
    return [e for e in events if e["event"] == "frame" and (g is None or e["generation"] == g)]


def test_progressive_frames_then_idle_and_the_image_of_render(session, tmp_path):
    data = small_scene(spp=4)
    assert level_scales(160, 120) == [4]                   # 40 × 30 first, then full resolution
    _start(session, tmp_path, data)
    updated = [e for e in session.log if e["event"] == "updated"][0]
    assert set(updated["rebuilt"]) >= {"camera", "film", "materials", "meshes", "soup", "bvh", "lights", "tables"}
    frames = _frames(session.log, 1)
    assert frames[0]["scale"] == 4 and (frames[0]["width"], frames[0]["height"]) == (40, 30)
    assert frames[0]["width"] * frames[0]["height"] <= LEVEL_PIXELS
    full = [f for f in frames if f["scale"] == 1]
    assert [f["spp"] for f in full] == sorted(f["spp"] for f in full) and full[-1]["spp"] == 4
    assert full[-1]["final"] and not any(f["final"] for f in frames[:-1])
    assert [f["frame"] for f in frames] == sorted(f["frame"] for f in frames)
    info, pixels = read_frame(full[-1]["path"])
    assert (info.generation, info.width, info.height, info.spp, info.final) == (1, 160, 120, 4, True)
    assert np.isfinite(pixels).all() and (pixels[..., 3] == 1).all()
    # The same PathTracer and film as `render`: for materials without layered walks (counter-based
    # random numbers only) the image is bit-identical to the final render at the same samples.
    reference = render(data, spp=4).film.combined().astype(np.float32)
    np.testing.assert_array_equal(pixels[..., :3], reference)


def test_a_crop_leaves_every_pixel_outside_it_empty(session, tmp_path):
    """A border render (film crop, edges not multiples of the reduced pass's divisor): the final
    frame is RGBA 0 outside the crop, also in the band the reduced pass's rounded-out crop covers,
    and rendered (alpha 1) inside it."""
    data = small_scene(spp=4)
    x0, y0, x1, y1 = 13, 10, 91, 67
    data["film"]["crop"] = [x0, y0, x1, y1]
    _start(session, tmp_path, data)
    frames = _frames(session.log, 1)
    assert frames[0]["scale"] == 4 and frames[-1]["final"]
    info, pixels = read_frame(frames[-1]["path"])
    inside = np.zeros((120, 160), bool)
    inside[y0:y1, x0:x1] = True
    assert (pixels[~inside] == 0).all()
    assert (pixels[inside][:, 3] == 1).all()


def test_each_edit_rebuilds_only_what_it_needs_and_restarts_accumulation(session, tmp_path):
    data = small_scene(spp=2)
    session.send(cmd="samples", samples=2)
    _start(session, tmp_path, data)
    base = read_frame(_frames(session.log, 1)[-1]["path"])[1]
    g = 1
    edits = []

    def edit(name, changes, expect):
        nonlocal g
        g += 1
        mark = len(session.log)
        session.send(cmd="update", generation=g, changes=changes)
        session.until(_idle(g))
        events = session.since(mark)
        updated = [e for e in events if e["event"] == "updated"]
        assert len(updated) == 1 and updated[0]["generation"] == g
        assert set(updated[0]["rebuilt"]) == expect, (name, updated[0]["rebuilt"])
        frames = _frames(events)
        assert frames and all(f["generation"] == g for f in frames), name
        full = [f["spp"] for f in frames if f["scale"] == 1]
        assert full[0] <= 2 and full[-1] == 2, (name, full)      # accumulation started again
        edits.append(name)
        return read_frame(frames[-1]["path"])[1]

    cam = copy.deepcopy(data["camera"])
    cam["to_world"][0][3] = 0.4
    moved = edit("camera", {"camera": cam}, {"camera"})
    assert not np.array_equal(moved, base)
    film = dict(data["film"], width=120, height=90)
    resized = edit("film", {"film": film}, {"film"})
    assert resized.shape == (90, 120, 4)
    red = edit("material", {"materials": {"paint": {"type": "diffuse", "color": [0.9, 0.1, 0.1]}}},
               {"materials", "tables"})
    lights = copy.deepcopy(data["lights"])
    lights[0]["power"] = 1200.0
    bright = edit("light", {"lights": lights}, {"lights", "tables"})
    assert bright[..., :3].mean() > red[..., :3].mean() * 1.5
    edit("world", {"world": {"type": "constant", "color": [0.6, 0.2, 0.2]}}, {"world", "tables"})
    objects = copy.deepcopy(data["objects"])
    objects[1]["to_world"] = [[1, 0, 0, 0.7], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    edit("transform", {"objects": objects}, {"soup", "bvh", "tables"})
    objects.append({"name": "second", "mesh": "box", "materials": ["paint"],
                    "to_world": [[1, 0, 0, -1.2], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]})
    edit("object added", {"objects": objects}, {"soup", "bvh", "tables"})
    edit("object removed", {"objects": objects[:2]}, {"soup", "bvh", "tables"})
    edit("mesh", {"meshes": {"floor": quad(s=4.0)}}, {"meshes", "soup", "bvh", "tables"})
    edit("settings", {"render": {"spp": 2, "max_bounces": 1, "seed": 5}}, {"settings", "tables"})
    assert len(edits) == 10


def test_frames_of_an_edited_generation_stop_at_once(session, tmp_path):
    """Edits sent while a long render runs: every frame after the newest generation's 'updated'
    event belongs to it, frames never go back to an older generation, and generations only grow."""
    data = small_scene(width=320, height=240)
    session.send(cmd="samples", samples=0)                  # render until told otherwise
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(data))
    session.until(lambda e: e["event"] == "ready")
    session.send(cmd="scene", generation=1, path=str(path))
    session.until(lambda e: e["event"] == "frame" and e["scale"] == 1 and e["spp"] >= 1)
    for g in range(2, 6):
        cam = copy.deepcopy(data["camera"])
        cam["to_world"][0][3] = 0.05 * g
        session.send(cmd="update", generation=g, changes={"camera": cam})
        time.sleep(0.05)
    session.until(lambda e: e["event"] == "frame" and e["generation"] == 5 and e["scale"] == 1 and e["spp"] >= 1)
    frames = _frames(session.log)
    generations = [f["generation"] for f in frames]
    assert generations == sorted(generations)
    updated5 = next(i for i, e in enumerate(session.log) if e["event"] == "updated" and e["generation"] == 5)
    assert all(f["generation"] == 5 for f in _frames(session.log[updated5:]))
    # the frame files agree with their events (a slot may only ever hold a newer frame)
    info, _ = read_frame(frames[-1]["path"])
    assert info.generation == 5 and info.frame >= frames[-1]["frame"]


def test_edits_waiting_together_are_applied_as_one(tmp_path):
    """Commands taken together (edits that arrived while a work item ran) make one rebuild with the
    newest generation and all their changes."""
    data = small_scene(width=32, height=24)
    events = []
    queue_items = []

    class Commands:
        def take(self, block):
            items, queue_items[:] = list(queue_items), []
            return items or [END]

        def restart_pending(self):
            return bool(queue_items)

    s = Session(tmp_path / "frames", workers=1, samples=1, events=lambda e, **f: events.append({"event": e, **f}),
                commands=Commands())
    s._handle([parse_command(json.dumps({"cmd": "scene", "generation": 1, "scene": data}))])
    lights = copy.deepcopy(data["lights"])
    lights[0]["power"] = 10.0
    mat = {"type": "diffuse", "color": [0.1, 0.9, 0.1]}
    s._handle([parse_command(json.dumps(m)) for m in (
        {"cmd": "update", "generation": 2, "changes": {"lights": lights}},
        {"cmd": "update", "generation": 3, "changes": {"materials": {"paint": mat}}},
        {"cmd": "update", "generation": 4, "changes": {"camera": data["camera"]}})])
    updated = [e for e in events if e["event"] == "updated"]
    assert [e["generation"] for e in updated] == [1, 4]
    assert set(updated[1]["rebuilt"]) == {"camera", "lights", "materials", "tables"}
    assert s.state.doc["lights"][0]["power"] == 10.0 and s.state.doc["materials"]["paint"] == mat
    assert s.progress.generation == 4
    assert s.run() == 0                                     # END: the loop ends, 'bye'
    assert events[-1]["event"] == "bye"


@pytest.mark.skipif(not LINUX, reason="reads the process CPU time from /proc")
def test_idle_session_uses_no_cpu(session, tmp_path):
    _start(session, tmp_path, small_scene())
    cpu0 = _cpu(session.proc.pid)
    time.sleep(2.0)
    used = _cpu(session.proc.pid) - cpu0
    assert used < 0.05 * 2.0, used                          # < 5 % of one core


def _cpu(pid):
    with open(f"/proc/{pid}/stat") as f:
        parts = f.read().rsplit(")", 1)[1].split()
    return (int(parts[11]) + int(parts[12])) / os.sysconf("SC_CLK_TCK")


def test_more_samples_continue_the_accumulation(session, tmp_path):
    _start(session, tmp_path, small_scene())
    mark = len(session.log)
    session.send(cmd="samples", samples=6)
    session.until(_idle(1))
    frames = [f for f in _frames(session.since(mark)) if f["scale"] == 1]
    assert frames[0]["spp"] > 4 and frames[-1]["spp"] == 6 and frames[-1]["final"]


def test_errors_are_reported_and_the_session_goes_on(session, tmp_path):
    session.until(lambda e: e["event"] == "ready")
    session.proc.stdin.write("this is not json\n")
    session.proc.stdin.flush()
    assert "not a JSON command" in session.until(lambda e: e["event"] == "error")["message"]
    session.send(cmd="update", generation=1, changes={"camera": {}})
    assert "before any scene" in session.until(lambda e: e["event"] == "error")["message"]
    session.send(cmd="update", generation=1, changes={"cameras": {}})
    assert "unknown section" in session.until(lambda e: e["event"] == "error")["message"]
    data = small_scene()
    bad = copy.deepcopy(data)
    bad["materials"]["paint"]["color"] = [2, 0]
    session.send(cmd="scene", generation=2, scene=bad)
    error = session.until(lambda e: e["event"] == "error")
    assert error["generation"] == 2 and not error["fatal"] and "materials.paint.color" in error["message"]
    session.send(cmd="update", generation=3, changes={"materials": {"paint": data["materials"]["paint"]}})
    session.until(_idle(3))
    session.send(cmd="ping", id=7)
    assert session.until(lambda e: e["event"] == "pong")["id"] == 7
    assert all("Traceback" not in str(e) for e in session.log)


def test_stop_end_of_input_and_sigterm_end_the_session(tmp_path):
    for how in ("stop", "eof", "sigterm"):
        s = SessionProcess(tmp_path / how)
        try:
            _start(s, tmp_path, small_scene(width=32, height=24))
            t0 = time.monotonic()
            if how == "stop":
                s.send(cmd="stop")
                s.until(lambda e: e["event"] == "bye")
            elif how == "eof":
                s.proc.stdin.close()
            else:
                s.proc.send_signal(signal.SIGTERM)
            assert s.proc.wait(10) == 0, how
            assert time.monotonic() - t0 < 5.0
        finally:
            s.close()


def test_an_internal_failure_is_one_fatal_event(tmp_path, monkeypatch):
    from backend.integrator import PathTracer
    from backend.session import loop

    def broken(self, *args, **kwargs):
        raise RuntimeError("kaputt")

    monkeypatch.setattr(PathTracer, "render", broken)
    events = []
    data = small_scene(width=32, height=24)

    class Commands:
        sent = False

        def take(self, block):
            if not self.sent:
                self.sent = True
                return [parse_command(json.dumps({"cmd": "scene", "generation": 1, "scene": data}))]
            return []

        def restart_pending(self):
            return False

    monkeypatch.setattr(loop, "EventWriter", lambda: lambda e, **f: events.append({"event": e, **f}))
    monkeypatch.setattr(loop, "CommandQueue", Commands)
    from backend.errors import LaminaError
    with pytest.raises(LaminaError, match="internal error: RuntimeError: kaputt"):
        loop.run_session(tmp_path / "frames", workers=1, samples=2)
    assert events[-1] == {"event": "error", "message": "internal error: RuntimeError: kaputt", "fatal": True}


def test_protocol_validation():
    with pytest.raises(ProtocolError, match="unknown command"):
        parse_command('{"cmd": "render"}')
    with pytest.raises(ProtocolError, match="generation"):
        parse_command('{"cmd": "update", "generation": -1, "changes": {}}')
    with pytest.raises(ProtocolError, match="'materials' must be an object"):
        parse_command('{"cmd": "update", "generation": 1, "changes": {"materials": []}}')
    with pytest.raises(ProtocolError, match="samples"):
        parse_command('{"cmd": "samples", "samples": -2}')
    assert parse_command('{"cmd": "stop"}') == {"cmd": "stop"}


def test_frame_files_are_replaced_whole(tmp_path):
    w = FrameWriter(tmp_path)
    img = np.random.default_rng(0).random((5, 7, 4)).astype(np.float32)
    p1, n1 = w.write(img, generation=3, spp=2, scale=1, final=False)
    p2, n2 = w.write(img * 2, generation=4, spp=1, scale=2, final=True)
    p3, n3 = w.write(img * 3, generation=4, spp=2, scale=1, final=True)
    assert (n1, n2, n3) == (1, 2, 3) and p1 == p3 != p2
    info, pixels = read_frame(p1)
    assert (info.frame, info.generation, info.width, info.height, info.spp, info.final) == (3, 4, 7, 5, 2, True)
    np.testing.assert_array_equal(pixels, img * 3)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["frame-0.bin", "frame-1.bin"]


def test_the_session_accepts_every_scene_render_accepts():
    # An exported scene with data passes and named views (Blender's Depth pass, a stereo camera)
    # renders with `render`; the viewport's session rendered nothing: "passes: unknown field".
    from backend.errors import LaminaError
    from backend.scene.loader import load_scene_data
    from backend.session.state import SessionScene
    data = small_scene(width=16, height=12)
    data["passes"] = {"depth": True, "normal": True}
    data["views"] = {"left": copy.deepcopy(data["camera"]), "right": copy.deepcopy(data["camera"])}
    load_scene_data(copy.deepcopy(data), "scene.json")            # what `render` accepts ...
    state = SessionScene()
    state.load(copy.deepcopy(data), "scene.json")                 # ... the session accepts
    assert state.ready
    state.update({"passes": {"mist": True}})                      # an edit of the passes alone
    assert state.ready
    # ... and what `render` refuses, the session refuses with the same words, keeping its scene.
    with pytest.raises(LaminaError) as render_error:
        load_scene_data(dict(copy.deepcopy(data), passes={"depht": True}), "scene.json")
    with pytest.raises(LaminaError) as session_error:
        state.update({"passes": {"depht": True}})
    assert str(session_error.value) == str(render_error.value)
    assert state.tracer is not None
