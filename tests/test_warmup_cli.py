"""``python -m backend warmup`` (backend/cli/warmup.py): compiles the kernels ahead of the first
render (farm nodes, the add-on's background compile) and says what it did in one line each."""
from __future__ import annotations

import json
import subprocess
import sys

from conftest import ROOT


def test_warm_cache_says_so_and_exits_0():
    # The suite's first test compiled the cache; a warm cache renders nothing here.
    out = subprocess.run([sys.executable, "-m", "backend", "warmup", "--progress", "json"], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    events = [json.loads(line) for line in out.stdout.splitlines()]
    assert [e["event"] for e in events][-1] == "warm" and "Traceback" not in out.stderr
    text = subprocess.run([sys.executable, "-m", "backend", "warmup"], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)
    assert text.returncode == 0 and text.stdout == ""
    assert text.stderr.strip().startswith("Lamina: render kernels are compiled (cached in "), text.stderr


def test_cold_cache_prints_one_line_before_and_one_after(monkeypatch, capsys, tmp_path):
    # The compile itself is the first-run test's (tests/test_kernels_core.py); here its words.
    import argparse

    from backend import warmup
    from backend.cli.warmup import cmd_warmup
    calls = []
    monkeypatch.setitem(warmup._STATE, "compiled", False)
    monkeypatch.setattr(warmup, "is_warm", lambda: False)
    monkeypatch.setattr(warmup, "marker", lambda: tmp_path / "warm")
    monkeypatch.setattr(warmup, "compile_layered_alongside", lambda: None)
    monkeypatch.setattr(warmup, "warm_up", lambda: calls.append("rendered the warm-up scenes"))
    assert cmd_warmup(argparse.Namespace(progress="text")) == 0
    lines = capsys.readouterr().err.splitlines()
    assert calls == ["rendered the warm-up scenes"] and (tmp_path / "warm").is_file()
    assert len(lines) == 2, lines
    assert lines[0] == "Lamina: compiling render kernels (first run only) ..."
    assert lines[1].startswith("Lamina: compiled render kernels in ") and " s (cached in " in lines[1]
