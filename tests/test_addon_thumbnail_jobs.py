"""The user-preset thumbnail queue (addon/presets/thumbnail_jobs.py, no bpy needed): one render at
a time in order, each started when the previous one ended, cancel, and the failure message.

The renderer is replaced by a fake ``backend`` package on PYTHONPATH that logs when it starts and
ends, so the order and overlap of renders are observed, not assumed."""
from __future__ import annotations

import importlib.util
import json
import os
import sys
import textwrap
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from conftest import ROOT

FAKE_MAIN = textwrap.dedent('''
    import json, os, sys, time
    preset = sys.argv[3]
    log = os.environ["FAKE_LOG"]
    with open(log, "a") as f:
        f.write(json.dumps({"preset": preset, "at": "start", "t": time.time()}) + "\\n")
    if preset.endswith("bad.json"):
        print("traceback noise", file=sys.stderr)
        print("error: bad.json: ior: must be > 1", file=sys.stderr)
        sys.exit(2)
    gate = os.environ.get("FAKE_GATE")          # a render may not end before this file exists
    deadline = time.time() + 60
    while gate and not os.path.exists(gate) and time.time() < deadline:
        time.sleep(0.01)
    time.sleep(float(os.environ.get("FAKE_SECONDS", "0.3")))
    with open(log, "a") as f:
        f.write(json.dumps({"preset": preset, "at": "end", "t": time.time()}) + "\\n")
''')


@pytest.fixture
def jobs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)        # ``python -m`` looks in the working directory first
    spec = importlib.util.spec_from_file_location("thumbnail_jobs_under_test",
                                                  ROOT / "addon" / "presets" / "thumbnail_jobs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module._forget_entries = lambda: None            # the preset list lives in the bpy layer
    fake = tmp_path / "fake" / "backend"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("")
    (fake / "__main__.py").write_text(FAKE_MAIN)
    log = tmp_path / "log.jsonl"
    env = dict(os.environ, PYTHONPATH=str(tmp_path / "fake"), FAKE_LOG=str(log))
    yield module, env, log
    module.cancel()


def events(log: Path) -> list[dict]:
    return [json.loads(l) for l in log.read_text().splitlines()] if log.exists() else []


def test_renders_run_one_at_a_time_in_request_order(jobs, tmp_path):
    module, env, log = jobs
    presets = [tmp_path / f"p{i}.json" for i in range(3)]
    gate = tmp_path / "gate"
    env["FAKE_GATE"] = str(gate)
    for p in presets:
        module.request(p, sys.executable, env)
    # Requesting does not wait for a render: none has ended yet. The fake renders cannot end
    # before the gate file exists, so a request that waited for its render would return only
    # after the fake's 60 s limit, with an end logged. (With a 2 s render and no gate, slow
    # process starts on a loaded machine failed this twice.)
    assert not [e for e in events(log) if e["at"] == "end"]
    gate.write_text("")
    assert module.wait(60)
    ev = events(log)
    assert [(Path(e["preset"]).name, e["at"]) for e in ev] == [
        ("p0.json", "start"), ("p0.json", "end"), ("p1.json", "start"), ("p1.json", "end"),
        ("p2.json", "start"), ("p2.json", "end")]
    done = module.finished()
    assert [Path(f["path"]).name for f in done] == ["p0.json", "p1.json", "p2.json"]
    assert all(f["code"] == 0 and not f["cancelled"] for f in done)


def test_requesting_again_replaces_the_running_render(jobs, tmp_path):
    module, env, log = jobs
    env["FAKE_SECONDS"] = "30"
    p = tmp_path / "same.json"
    module.request(p, sys.executable, env)
    deadline = time.monotonic() + 20
    while not events(log) and time.monotonic() < deadline:   # the first render is running
        time.sleep(0.02)
    env["FAKE_SECONDS"] = "0.2"
    t0 = time.monotonic()
    module.request(p, sys.executable, env)
    assert module.wait(60) and time.monotonic() - t0 < 15    # not the 30 s of the first
    done = module.finished()
    assert [f["cancelled"] for f in done] == [True, False] and done[1]["code"] == 0


def test_cancel_everything_stops_the_running_render_and_drops_the_queue(jobs, tmp_path):
    module, env, log = jobs
    env["FAKE_SECONDS"] = "30"
    for i in range(3):
        module.request(tmp_path / f"q{i}.json", sys.executable, env)
    t0 = time.monotonic()
    module.cancel()
    assert time.monotonic() - t0 < 10 and not module.busy()
    assert [f["cancelled"] for f in module.finished()] == [True]   # q1, q2 never started
    assert {Path(e["preset"]).name for e in events(log)} <= {"q0.json"}


def test_a_failed_render_reports_the_last_line_of_its_error_output(jobs, tmp_path, capsys):
    module, env, log = jobs
    module.request(tmp_path / "bad.json", sys.executable, env)
    assert module.wait(60)
    (f,) = module.finished()
    assert f["code"] == 2 and not f["cancelled"]
    assert f["message"] == "error: bad.json: ior: must be > 1"
    assert "thumbnail of bad.json failed: error: bad.json: ior: must be > 1" in capsys.readouterr().err


class FakeTimers:
    """Stands in for ``bpy.app.timers`` (headless Blender never runs timers): records the
    registration and lets the test fire the callback the way Blender's event loop would."""

    def __init__(self):
        self.registered = []

    def register(self, fn, first_interval=0.0, persistent=False):
        self.registered.append({"fn": fn, "first_interval": first_interval, "persistent": persistent})

    def is_registered(self, fn):
        return any(r["fn"] is fn for r in self.registered)

    def unregister(self, fn):
        self.registered = [r for r in self.registered if r["fn"] is not fn]


def test_in_blender_a_timer_drives_the_queue_redraws_and_stops_when_idle(jobs, tmp_path, monkeypatch):
    module, env, log = jobs
    timers = FakeTimers()
    fake_bpy = type(sys)("bpy")
    fake_bpy.app = type(sys)("bpy.app")
    fake_bpy.app.timers = timers
    redraws = []
    area = lambda kind: SimpleNamespace(type=kind, tag_redraw=lambda: redraws.append(kind))
    screen = SimpleNamespace(areas=[area("VIEW_3D"), area("PROPERTIES")])
    fake_bpy.context = SimpleNamespace(window_manager=SimpleNamespace(windows=[SimpleNamespace(screen=screen)]))
    monkeypatch.setitem(sys.modules, "bpy", fake_bpy)
    for i in range(2):
        module.request(tmp_path / f"t{i}.json", sys.executable, env)
    # One timer for the whole queue, kept across file loads (persistent).
    assert len(timers.registered) == 1 and timers.registered[0]["persistent"]
    tick = timers.registered[0]["fn"]
    deadline = time.monotonic() + 60
    intervals = []
    while True:                                   # Blender calls the tick until it returns None
        nxt = tick()
        intervals.append(nxt)
        if nxt is None:
            timers.unregister(tick)               # what Blender does with a timer returning None
            break
        if time.monotonic() > deadline:
            break
        time.sleep(0.02)
    assert intervals[-1] is None and set(intervals[:-1]) == {module.POLL_SECONDS}
    assert [Path(f["path"]).name for f in module.finished()] == ["t0.json", "t1.json"]
    assert redraws == ["PROPERTIES", "PROPERTIES"]   # the preset panel, once per finished thumbnail
    assert [(Path(e["preset"]).name, e["at"]) for e in events(log)] == [
        ("t0.json", "start"), ("t0.json", "end"), ("t1.json", "start"), ("t1.json", "end")]
    module.request(tmp_path / "t2.json", sys.executable, env)      # idle again: a new timer
    assert timers.is_registered(tick) and len(timers.registered) == 1
    module.cancel()
    module.stop_ticking()                         # add-on unload
    assert not timers.is_registered(tick)
