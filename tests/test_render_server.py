"""The render server (``python -m backend serve``, backend/cli/serve.py) and the add-on's client for
it (addon/engine/render_server.py, no bpy): jobs give the same images as ``render``, one after
the other in one process; cancel keeps the server; failures are one job's exit, not the server's."""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from test_session import small_scene

from backend.imageio import read_exr

_pkg = importlib.util.spec_from_file_location("lamina_engine_pkg", ROOT / "addon" / "engine" / "__init__.py",
                                              submodule_search_locations=[str(ROOT / "addon" / "engine")])
if "lamina_engine_pkg" not in sys.modules:
    _module = importlib.util.module_from_spec(_pkg)
    sys.modules["lamina_engine_pkg"] = _module
    _pkg.loader.exec_module(_module)
from lamina_engine_pkg.job import child_environment  # noqa: E402
from lamina_engine_pkg.render_server import JOBS_PER_SERVER, RenderServer, ServerPool  # noqa: E402

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups (POSIX)")


def _scene_file(tmp: Path, name="scene.json", **kw) -> Path:
    path = tmp / name
    path.write_text(json.dumps(small_scene(**kw)))
    return path


def _finish(job) -> tuple[int, list[dict]]:
    events = []
    while not job.finished():
        events += job.poll(0.2)
    return job.wait(), events


def _pixels(path: Path) -> np.ndarray:
    pixels, names = read_exr(path)
    return pixels[:, :, [names.index(c) for c in "RGBA"]]


@pytest.fixture
def server():
    s = RenderServer(sys.executable, child_environment({"PYTHONHASHSEED": "0"}))
    yield s
    s.stop()


def test_jobs_render_the_same_image_as_render_in_one_process(tmp_path, server):
    scene = _scene_file(tmp_path, width=48, height=32, spp=4)
    cold = tmp_path / "cold.exr"
    subprocess.run([sys.executable, "-m", "backend", "render", str(scene), "-o", str(cold), "--workers", "2"],
                   cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)), check=True, capture_output=True)
    images, kinds = [], []
    for i in range(2):
        out = tmp_path / f"warm-{i}.exr"
        job = server.submit([str(scene), "-o", str(out), "--workers", "2"])
        status, events = _finish(job)
        assert status == 0, job.failure_message()
        kinds.append([e["event"] for e in events])
        images.append(_pixels(out))
    pid = server.job.proc.pid
    assert server.alive and server.jobs_done == 2
    assert "done" in kinds[0] and "done" in kinds[1] and "start" in kinds[1]
    # Same seed, same scene: the same pixels as a new process gives, job after job.
    np.testing.assert_array_equal(images[0], _pixels(cold))
    np.testing.assert_array_equal(images[1], images[0])
    assert server.job.proc.pid == pid


def test_a_failed_job_is_its_exit_and_the_server_renders_the_next(tmp_path, server):
    job = server.submit([str(tmp_path / "missing.json"), "-o", str(tmp_path / "x.exr")])
    status, events = _finish(job)
    assert status == 2 and "scene file not found" in job.failure_message()
    assert any(e["event"] == "error" for e in events)
    job = server.submit([str(tmp_path / "missing.json")])              # no -o: argparse's message
    status, _ = _finish(job)
    assert status == 2 and "-o/--output" in job.failure_message()
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "lamina-scene", "version": 1, "film": {"width": -3}}')
    status, _ = _finish(server.submit([str(bad), "-o", str(tmp_path / "b.exr")]))
    assert status == 2
    scene = _scene_file(tmp_path, width=16, height=16, spp=1)
    status, _ = _finish(server.submit([str(scene), "-o", str(tmp_path / "ok.exr"), "--workers", "1"]))
    assert status == 0 and (tmp_path / "ok.exr").is_file()
    assert server.alive


def test_cancel_ends_the_job_with_what_is_done_and_keeps_the_server(tmp_path, server):
    scene = _scene_file(tmp_path, width=160, height=120, spp=20000)
    partial = tmp_path / "partial.npy"
    job = server.submit([str(scene), "-o", str(tmp_path / "long.exr"), "--workers", "1",
                         "--partial", str(partial), "--partial-interval", "0.2"])
    seen = []
    while not any(e["event"] == "partial" for e in seen):       # rendering for real by now
        seen += job.poll(0.2)
        assert not job.finished(), job.failure_message()
    pid = server.job.proc.pid
    job.cancel()
    assert job.done and _finish(job)[0] == 130                   # render's status when stopped
    assert (tmp_path / "long.exr").is_file()                     # what was done is written
    assert server.alive and server.job.proc.pid == pid
    status, _ = _finish(server.submit([str(_scene_file(tmp_path, "s2.json", width=16, height=16, spp=1)),
                                       "-o", str(tmp_path / "next.exr"), "--workers", "1"]))
    assert status == 0


@linux_only
def test_a_server_that_dies_fails_its_job_and_the_pool_starts_a_new_one(tmp_path):
    pool = ServerPool()
    env = child_environment()
    scene = _scene_file(tmp_path, width=160, height=120, spp=20000)
    try:
        job = pool.job_for("final", sys.executable, env, [str(scene), "-o", str(tmp_path / "a.exr"),
                                                          "--workers", "1"])
        # A second final render while the first runs: not shared (the caller starts a process).
        assert pool.job_for("final", sys.executable, env, [str(scene), "-o", str(tmp_path / "b.exr")]) is None
        server = pool.servers["final"]
        while not any(e["event"] == "start" for e in job.poll(0.2)):
            assert not job.finished(), job.failure_message()
        os.killpg(server.job.proc.pid, 9)
        status, _ = _finish(job)
        assert status != 0 and "signal 9" in job.failure_message()
        small = _scene_file(tmp_path, "small.json", width=16, height=16, spp=1)
        job2 = pool.job_for("final", sys.executable, env, [str(small), "-o", str(tmp_path / "c.exr")])
        assert pool.servers["final"] is not server
        status, _ = _finish(job2)
        assert status == 0
        # Another environment (the preferences changed): another server.
        first = pool.servers["final"]
        job3 = pool.job_for("final", sys.executable, dict(env, LAMINA_TEST_MARK="1"),
                            [str(small), "-o", str(tmp_path / "d.exr")])
        assert _finish(job3)[0] == 0 and pool.servers["final"] is not first and not first.alive
    finally:
        pool.stop_all()


def test_the_raw_protocol_cancel_before_start_ping_and_end_of_input(tmp_path):
    scene = _scene_file(tmp_path, width=16, height=16, spp=1)
    lines = [{"cmd": "ping"}, {"cmd": "cancel", "job": "b"},
             {"cmd": "render", "job": "a", "args": [str(scene), "-o", str(tmp_path / "a.exr")]},
             {"cmd": "render", "job": "b", "args": [str(scene), "-o", str(tmp_path / "b.exr")]},
             {"cmd": "render", "job": "c", "args": "not a list"}, {"cmd": "what"}]
    proc = subprocess.run([sys.executable, "-m", "backend", "serve"], input="\n".join(map(json.dumps, lines)) + "\n",
                          capture_output=True, text=True, cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    events = [json.loads(l) for l in proc.stdout.splitlines()]
    exits = {e["job"]: e for e in events if e["event"] == "exit"}
    assert exits["a"]["status"] == 0 and (tmp_path / "a.exr").is_file()
    assert exits["b"]["status"] == 130 and not (tmp_path / "b.exr").exists()
    assert exits["c"]["status"] == 2 and "list of strings" in exits["c"]["message"]
    assert [e["event"] for e in events].count("pong") == 1
    assert any(e["event"] == "warning" and "what" in e["message"] for e in events)
    assert next(e for e in events if e["event"] == "ready")["protocol"] == 1
    # Every event of a job carries its id; stdout holds nothing but events.
    assert all("job" in e for e in events if e["event"] in ("start", "progress", "done"))


def test_the_pool_replaces_a_server_after_its_jobs_and_never_shares_a_busy_one():
    class Stub:
        made = []

        def __init__(self, python, env):
            self.key = (python, tuple(sorted((env or {}).items())))
            self.alive, self.busy, self.jobs_done, self.stopped = True, False, 0, False
            Stub.made.append(self)

        def submit(self, args):
            self.jobs_done += 1
            return ("job", self, tuple(args))

        def stop(self):
            self.stopped, self.alive = True, False

    pool = ServerPool(factory=Stub)
    first = pool.job_for("final", "py", {}, ["a"])[1]
    for _ in range(JOBS_PER_SERVER - 1):
        assert pool.job_for("final", "py", {}, ["a"])[1] is first
    second = pool.job_for("final", "py", {}, ["a"])[1]
    assert second is not first and first.stopped          # replaced after JOBS_PER_SERVER jobs
    second.busy = True
    assert pool.job_for("final", "py", {}, ["a"]) is None   # busy: the caller starts its own process
    assert pool.job_for("preview", "py", {}, ["a"])[1] is not second   # one server per purpose
    pool.stop_all()
    assert second.stopped and not pool.servers
