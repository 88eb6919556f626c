"""The add-on's backend process runner (addon/engine/job.py, no bpy): events, errors, cleanup."""
from __future__ import annotations

import importlib.util
import os
import sys
import textwrap
import time

import pytest

from conftest import ROOT

spec = importlib.util.spec_from_file_location("addon_job", ROOT / "addon" / "engine" / "job.py")
job_module = importlib.util.module_from_spec(spec)
spec.loader.exec_module(job_module)
BackendJob = job_module.BackendJob

posix_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups + /proc (Linux)")


def run_python(code: str, **kwargs) -> "BackendJob":
    return BackendJob([sys.executable, "-c", textwrap.dedent(code)], **kwargs)


def collect(job, timeout=20.0):
    events, t0 = [], time.monotonic()
    while not job.finished():
        events += job.poll(0.05)
        assert time.monotonic() - t0 < timeout, "the job did not finish"
    events += job.poll(0.0)
    return events, job.wait(5)


def start_time(pid: int):
    """Kernel start time of a process (with the PID it identifies the process: PIDs get reused)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return int(f.read().rsplit(")", 1)[1].split()[19])
    except (FileNotFoundError, ProcessLookupError):
        return None


def alive(pid: int, started, settle: float = 2.0) -> bool:
    """Still running ``settle`` seconds later: same PID *and* start time, and not a zombie.
    (A SIGKILLed process closes its files first and may show as running for a moment.)"""
    deadline = time.monotonic() + settle
    while True:
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except FileNotFoundError:
            return False
        if fields[0] == "Z" or int(fields[19]) != started:
            return False
        if time.monotonic() > deadline:
            return True
        time.sleep(0.02)


def test_events_and_plain_lines():
    job = run_python("""
        import json, sys
        print(json.dumps({"event": "progress", "fraction": 0.5}), flush=True)
        print("not json", flush=True)
        print("error: scene.json: materials.x: bad value", file=sys.stderr)
        sys.exit(2)
    """)
    events, code = collect(job)
    assert events == [{"event": "progress", "fraction": 0.5}, {"event": "log", "message": "not json"}]
    assert code == 2 and job.failure_message() == "scene.json: materials.x: bad value"


def test_traceback_tail_is_the_failure_message():
    job = run_python("raise ValueError('boom')")
    _, code = collect(job)
    assert code == 1 and job.failure_message() == "ValueError: boom"


@posix_only
def test_cancel_kills_a_child_that_ignores_sigterm_and_its_children(tmp_path):
    pids = tmp_path / "pids"
    job = run_python(f"""
        import os, signal, subprocess, sys, time
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        kid = subprocess.Popen([sys.executable, "-c", "import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); time.sleep(60)"])
        def start(pid):
            return open(f"/proc/{{pid}}/stat").read().rsplit(")", 1)[1].split()[19]
        open({str(pids)!r}, "w").write(f"{{os.getpid()}} {{start(os.getpid())}} {{kid.pid}} {{start(kid.pid)}}")
        while True:
            print('{{"event": "progress"}}', flush=True)
            time.sleep(0.05)
    """)
    t0 = time.monotonic()
    while not pids.exists() and time.monotonic() - t0 < 10:
        job.poll(0.05)
    t1 = time.monotonic()
    job.cancel(grace=0.5)
    latency = time.monotonic() - t1
    assert latency < 0.5 + 1.0
    values = list(map(int, pids.read_text().split()))
    for pid, started in zip(values[::2], values[1::2]):
        assert not alive(pid, started)


@posix_only
def test_strays_of_a_crashed_child_are_killed(tmp_path):
    pids = tmp_path / "pids"
    job = run_python(f"""
        import subprocess, sys
        kid = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
        start = open(f"/proc/{{kid.pid}}/stat").read().rsplit(")", 1)[1].split()[19]
        open({str(pids)!r}, "w").write(f"{{kid.pid}} {{start}}")
        raise RuntimeError("crashed, leaving a worker behind")
    """)
    t0 = time.monotonic()
    _, code = collect(job)
    assert code == 1
    assert time.monotonic() - t0 < 5                # the stray does not hold the job up
    pid, started = map(int, pids.read_text().split())
    assert not alive(pid, started)


def test_no_thread_is_started_and_output_is_read_from_files_that_are_removed(tmp_path):
    """Blender does not support Python threads: the job reads the child's output without any.
    Output far beyond a pipe's buffer (64 KiB) does not block the child; a last line without a
    newline still arrives; the temporary files are gone after ``wait``."""
    import threading
    before = threading.active_count()
    job = run_python("""
        import json, sys
        for i in range(20000):
            print(json.dumps({"event": "progress", "done": i}))
        sys.stderr.write(("noise " * 40 + "\\n") * 5000)
        sys.stdout.write("no newline at the end")
    """)
    assert threading.active_count() == before
    files = [job._out.path, job._err.path]
    assert all(os.path.exists(f) for f in files)
    events, code = collect(job)
    assert code == 0 and threading.active_count() == before
    assert [e["done"] for e in events[:-1]] == list(range(20000))
    assert events[-1] == {"event": "log", "message": "no newline at the end"}
    assert job.stderr_text().count("\n") == job_module.STDERR_LINES - 1   # the tail is kept
    assert not any(os.path.exists(f) for f in files)


def test_child_environment_finds_backend_and_dependencies():
    env = job_module.child_environment({"EXTRA": "1"})
    paths = env["PYTHONPATH"].split(os.pathsep)
    assert paths[0] == str(ROOT) and env["EXTRA"] == "1"
    import subprocess
    out = subprocess.run([sys.executable, "-c", "import backend, numpy, embreex; print(backend.__file__)"],
                         env=env, capture_output=True, text=True, cwd="/")
    assert out.returncode == 0, out.stderr
    assert os.path.realpath(out.stdout.strip()).startswith(os.path.realpath(ROOT))
