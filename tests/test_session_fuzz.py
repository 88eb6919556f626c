"""Issue 39: the session (the engine behind Blender's Rendered viewport) never dies or hangs on an
input line. A seeded, bounded fuzz of command lines (malformed JSON, deep nesting, huge numbers,
NaN/Inf, wrong types, unknown commands, edits to missing objects) is fed to a session in small
batches, each line answered: a ping by its pong, a malformed line by a non-fatal error, a scene or
update by 'updated' or a non-fatal error; the session then still renders and ends at end of input.
The exact lines of the issue also go through the real process (its stdin reader thread)."""
from __future__ import annotations

import copy
import json
import random
import threading
import time

from test_session import SessionProcess, small_scene

from backend.session.loop import Session
from backend.session.protocol import END, CommandQueue, ProtocolError, read_command

SEED = 39
LINES = 300

#: The issue's lines: each killed the reader, ended the session silently or fatally.
ISSUE_LINES = [
    "[" * 100_000,
    '{"cmd": "ping", "id": ' + "9" * 5000 + "}",
    '{"cmd": "ping", "id": NaN}',
    '{"cmd": "ping", "id": 1e400}',
    '{"cmd": "scene", "generation": %d, "scene": {}}' % 2 ** 64,
    '{"cmd": "scene", "generation": 1, "scene": {}, "base": 5}',
]


def _values(rng: random.Random):
    """Values of every JSON kind, the hostile ones included."""
    return rng.choice([None, True, False, 0, -1, 1.5, 2 ** 63, 2 ** 64, 10 ** 400, 1e308, float("nan"),
                       float("inf"), -float("inf"), "", "x" * 5000, "\x00", [], [1, 2], {}, {"a": 1},
                       "/nonexistent/dir/scene.json"])


def _dump(value) -> str:
    return json.dumps(value)               # NaN and Infinity as Python writes them (not JSON)


def fuzz_lines(seed: int, count: int, scene: dict) -> list[str]:
    rng = random.Random(seed)
    good = [
        {"cmd": "scene", "generation": 1, "scene": scene},
        {"cmd": "update", "generation": 2, "changes": {"materials": {"paint": {"type": "diffuse", "color": 0.3}}}},
        {"cmd": "update", "generation": 3, "changes": {"camera": scene["camera"]}},
        {"cmd": "update", "generation": 4, "changes": {"lights": scene["lights"]}},
        {"cmd": "samples", "samples": 2},
        {"cmd": "ping", "id": "p"},
    ]
    missing = [   # edits that name objects that are not there
        {"cmd": "update", "generation": 5, "changes": {"materials": {"nope": None}}},
        {"cmd": "update", "generation": 5, "changes": {"meshes": {"ghost": None}}},
        {"cmd": "update", "generation": 5, "changes": {"objects": [{"mesh": "ghost", "materials": ["paint"]}]}},
        {"cmd": "update", "generation": 5, "changes": {"objects": [{"mesh": "box", "materials": ["ghost"]}]}},
        {"cmd": "update", "generation": 5, "changes_file": "/nonexistent/update.json"},
        {"cmd": "scene", "generation": 5, "path": "/nonexistent/scene.json"},
    ]
    lines = []
    for _ in range(count):
        kind = rng.randrange(8)
        base = copy.deepcopy(rng.choice(good))
        if kind == 0:                                          # malformed JSON
            text = _dump(base)
            cut = rng.randrange(1, len(text))
            lines.append(rng.choice([text[:cut], text[:cut] + "}" * rng.randrange(3), "{" + text,
                                     text.replace('"', "'", 1), "\xff\xfe garbage", "nul\x00l"]))
        elif kind == 1:                                        # deep nesting
            depth = rng.choice([65, 1000, 100_000])
            lines.append(rng.choice(["[" * depth, '{"cmd": "ping", "id": ' + "[" * depth + "]" * depth + "}",
                                     '{"cmd": "update", "generation": 9, "changes": {"world": '
                                     + '{"a": ' * depth + "1" + "}" * depth + "}}"]))
        elif kind == 2:                                        # huge numbers, NaN/Inf
            field = rng.choice(["generation", "samples", "id"])
            base["cmd"] = {"generation": rng.choice(["scene", "update"]), "samples": "samples", "id": "ping"}[field]
            if base["cmd"] == "update":
                base.setdefault("changes", {})
            base.setdefault("generation", 1)
            number = rng.choice(["9" * 5000, str(2 ** 64), str(2 ** 63), "1e400", "-1e400", "NaN",
                                 "Infinity", "-Infinity", "-0", "1.5"])
            lines.append(_dump(base)[:-1] + f', "{field}": {number}}}')
        elif kind == 3:                                        # wrong types
            key = rng.choice(sorted(base))
            base[key] = _values(rng)
            lines.append(_dump(base))
        elif kind == 4:                                        # unknown commands and fields
            lines.append(_dump(rng.choice([{"cmd": "render"}, {"cmd": None}, {"command": "ping"}, {},
                                           [], "ping", 7, {"cmd": ["ping"]}, {"cmd": "ping", "extra": [1]}])))
        elif kind == 5:
            lines.append(_dump(rng.choice(missing)))
        elif kind == 6:                                        # scene sections of the wrong kind
            section = rng.choice(["film", "camera", "render", "materials", "meshes", "objects", "lights", "world"])
            lines.append(_dump({"cmd": "update", "generation": rng.randrange(1, 12),
                                "changes": {section: _values(rng)}}))
        else:                                                  # valid: a fresh scene half the time
            lines.append(_dump(good[0] if rng.random() < 0.5 else base))
    return lines


class Batches:
    """Hands the session the lines in seeded batches of 1-3, each parsed as the stdin reader
    parses it (``read_command``), and records where each batch's answers start."""

    def __init__(self, lines: list[str], events: list, rng: random.Random):
        self.batches, i = [], 0
        while i < len(lines):
            n = rng.randint(1, 3)
            self.batches.append(lines[i:i + n])
            i += n
        self.events = events
        self.marks: list[int] = []
        self.items: list[list] = []

    def take(self, block):
        self.marks.append(len(self.events))
        if len(self.items) == len(self.batches):
            return [END]
        items = [read_command(line) for line in self.batches[len(self.items)]]
        self.items.append(items)
        return items

    def restart_pending(self):
        return False


def _run(session: Session, seconds: float) -> int:
    """``session.run()`` in a thread; a session that has not ended after ``seconds`` hangs."""
    out = {}
    thread = threading.Thread(target=lambda: out.update(code=session.run()), daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), "the session hangs"
    return out["code"]


def test_every_fuzzed_line_is_answered_and_the_session_lives_on(tmp_path):
    t0 = time.perf_counter()
    scene = small_scene(width=16, height=12)
    lines = fuzz_lines(SEED, LINES, scene) + ISSUE_LINES
    # The session starts with a scene and ends with edits that render, after all the fuzz.
    lines = [json.dumps({"cmd": "scene", "generation": 1, "scene": scene})] + lines + [
        json.dumps({"cmd": "scene", "generation": 100, "scene": scene}),
        json.dumps({"cmd": "ping", "id": "last"})]
    events: list[dict] = []
    commands = Batches(lines, events, random.Random(SEED))
    session = Session(tmp_path / "frames", workers=1, samples=1,
                      events=lambda e, **f: events.append({"event": e, **f}), commands=commands)
    assert _run(session, 120) == 0
    assert events[-1]["event"] == "bye"
    assert not [e for e in events if e["event"] == "error" and e.get("fatal")]
    assert all("Traceback" not in json.dumps(e) for e in events)
    json.dumps(events, allow_nan=False)                      # every event was strict JSON
    refused = edits = 0
    for b, items in enumerate(commands.items):
        answers = events[commands.marks[b]:commands.marks[b + 1]]
        errors = [e for e in answers if e["event"] == "error"]
        pongs = [e["id"] for e in answers if e["event"] == "pong"]
        bad = [i for i in items if isinstance(i, ProtocolError)]
        good = [i for i in items if not isinstance(i, ProtocolError)]
        refused += len(bad)
        # Each refused line: one non-fatal error naming no generation; each ping: its pong.
        assert len([e for e in errors if "generation" not in e]) == len(bad), (commands.batches[b], answers)
        assert pongs == [i.get("id") for i in good if i["cmd"] == "ping"], (commands.batches[b], answers)
        if any(i["cmd"] in ("scene", "update") for i in good):
            edits += 1
            built = [e for e in answers if e["event"] == "updated" or
                     (e["event"] == "error" and "generation" in e)]
            assert len(built) == 1, (commands.batches[b], answers)
    # The fuzz reaches every outcome in numbers (a fuzzer whose every line fails tests little).
    assert refused >= 100 and edits >= 40, (refused, edits)
    assert len([e for e in events if e["event"] == "updated"]) >= 15
    # After all of it the session still renders: the last scene's frames, then its pong.
    last = events.index(next(e for e in events if e["event"] == "updated" and e["generation"] == 100))
    assert any(e["event"] == "frame" and e["generation"] == 100 for e in events[last:])
    assert [e["id"] for e in events if e["event"] == "pong"][-1] == "last"
    print(f"{len(lines)} lines in {len(commands.items)} batches, {refused} refused, {edits} edit "
          f"batches, {time.perf_counter() - t0:.1f} s")


def test_a_failing_update_and_its_fix_in_one_batch_apply_the_fix(tmp_path):
    """issue 39: the fix was dropped, the error carried the fix's generation."""
    scene = small_scene(width=16, height=12)
    events: list[dict] = []
    fix = {"type": "diffuse", "color": [0.1, 0.8, 0.1]}
    lines = [json.dumps({"cmd": "scene", "generation": 1, "scene": scene}),
             json.dumps({"cmd": "update", "generation": 2, "changes": {"materials": {"paint": {"type": "diffuse", "color": [2, 0]}}}}),
             json.dumps({"cmd": "update", "generation": 3, "changes": {"materials": {"paint": fix}}})]
    commands = Batches(lines, events, random.Random(0))
    commands.batches = [lines[:1], lines[1:]]
    session = Session(tmp_path / "frames", workers=1, samples=1,
                      events=lambda e, **f: events.append({"event": e, **f}), commands=commands)
    assert _run(session, 60) == 0
    assert not [e for e in events if e["event"] == "error"], events
    assert [e["generation"] for e in events if e["event"] == "updated"] == [1, 3]
    assert session.state.doc["materials"]["paint"] == fix
    # The other order, fix first: the batch ends broken, and says so with its generation.
    events.clear()
    commands = Batches([], events, random.Random(0))
    commands.batches = [lines[:1], [lines[2], lines[1]]]
    session = Session(tmp_path / "frames2", workers=1, samples=1,
                      events=lambda e, **f: events.append({"event": e, **f}), commands=commands)
    assert _run(session, 60) == 0
    errors = [e for e in events if e["event"] == "error"]
    assert len(errors) == 1 and "materials.paint.color" in errors[0]["message"] and not errors[0]["fatal"]


def test_the_stdin_reader_survives_every_line_and_end_of_input_ends_the_session(tmp_path):
    """All fuzz lines through a real CommandQueue (its reader thread), then end of input."""
    import io
    scene = small_scene(width=16, height=12)
    lines = fuzz_lines(SEED + 1, 100, scene) + ISSUE_LINES + [json.dumps({"cmd": "ping", "id": "after"})]
    events: list[dict] = []
    session = Session(tmp_path / "frames", workers=1, samples=1,
                      events=lambda e, **f: events.append({"event": e, **f}),
                      commands=CommandQueue(io.StringIO("\n".join(lines) + "\n")))
    assert _run(session, 120) == 0
    assert events[-1]["event"] == "bye"
    assert [e["id"] for e in events if e["event"] == "pong"][-1] == "after"
    assert not [e for e in events if e["event"] == "error" and e.get("fatal")]


def test_the_issues_lines_through_the_session_process(tmp_path):
    """The process itself: each line of the issue gets a non-fatal error, a ping after them its
    pong, and closing stdin (also in the middle of a render) ends it with status 0."""
    s = SessionProcess(tmp_path, samples=100000, workers=1)
    scene = small_scene(width=64, height=48)
    try:
        s.until(lambda e: e["event"] == "ready")
        s.proc.stdin.write("\n".join(ISSUE_LINES) + "\n")
        s.send(cmd="ping", id=1)
        s.until(lambda e: e["event"] == "pong", timeout=60)
        s.send(cmd="scene", generation=2, scene=scene)
        s.until(lambda e: e["event"] == "frame", timeout=60)     # rendering: close stdin now
        t0 = time.monotonic()
        s.proc.stdin.close()
        s.until(lambda e: e["event"] == "bye", timeout=30)
        assert s.proc.wait(10) == 0
        assert time.monotonic() - t0 < 10
        err = s.proc.stderr.read()
    finally:
        s.close()
    errors = [e for e in s.log if e["event"] == "error"]
    assert len(errors) == len(ISSUE_LINES) and not any(e["fatal"] for e in errors), errors
    assert "Traceback" not in err
