"""``python -m backend ies info / plot``: figures agree with the README index; errors are one line."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from ies_reference import parse_readme_table

ROOT = Path(__file__).resolve().parent.parent
IES_DIR = ROOT / "tests" / "data" / "ies"
README = {r["file"].strip("`"): r for r in parse_readme_table(IES_DIR / "README.md")}


def _run(*args):
    return subprocess.run([sys.executable, "-m", "backend", "ies", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("name", ["qssi_roadway_typeIII_bilateral180_lm95.ies",
                                  "rab_ffled_flood_typeB_lm02.ies",
                                  "eulumdat_tilt_include_synthetic_lm02.ies"])
def test_info_json(name):
    r = _run("info", "--json", str(IES_DIR / name))
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    row = README[name]
    nv = int(row["#V (range)"].split()[0])
    nh = int(row["#H (range)"].split()[0])
    assert info["vertical_angles"]["count"] == nv and info["horizontal_angles"]["count"] == nh
    assert info["photometric_type"] == row["type"] and info["tilt"] == row["TILT"]
    assert abs(info["peak"]["candela"] - float(row["peak cd"])) <= 0.5
    assert info["lumens_integrated"] > 0 and isinstance(info["keywords"], list)
    if row["TILT"] == "INCLUDE":
        assert info["tilt_block"]["applied"] is False


def test_info_text_lists_the_essentials():
    r = _run("info", str(IES_DIR / "hew_overhead_quad90_8lamps_lm95.ies"))
    assert r.returncode == 0, r.stderr
    out = r.stdout
    for text in ("LM-63-1995", "photometric type   C", "vertical angles    19 (0..90°)",
                 "horizontal angles  5 (0..90°)", "symmetry           quadrilateral",
                 "lamps              8 × 5000 lm", "lumens stated      40,000.0",
                 "19,267.0 cd at file angles H = 45°, V = 10°; local direction [-0.123, -0.123, -0.985]", "[LUMINAIRE] 8/54W"):
        assert text in out, text


def test_plot_writes_png(tmp_path):
    out = tmp_path / "roadway.png"
    r = _run("plot", str(IES_DIR / "qssi_roadway_typeIII_bilateral180_lm95.ies"), "-o", str(out))
    assert r.returncode == 0, r.stderr
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.ies"
    bad.write_text("IESNA:LM-63-2002\n[TEST] x\n1 -1 1 3 1 1 2 0 0 0\n")
    r = _run("info", str(bad))
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {bad}: line 3: expected a 'TILT=NONE'")
    r = _run("plot", str(tmp_path / "missing.ies"), "-o", str(tmp_path / "x.png"))
    assert r.returncode == 2 and "IES file not found" in r.stderr and "Traceback" not in r.stderr


def test_plot_outputs_that_cannot_be_written_are_one_line(tmp_path):
    """A format matplotlib cannot write, a missing extension (matplotlib would add '.png' to a
    name other than the one printed), a folder or an unwritable place: one error line."""
    ies = str(IES_DIR / "qssi_roadway_typeIII_bilateral180_lm95.ies")
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    for out, message in [(tmp_path / "p.xyz", "cannot write '.xyz' plots (use one of:"),
                         (tmp_path / "noext", "cannot write 'no extension' plots"),
                         (tmp_path, "is a folder; give a file name"),
                         (blocker / "p.png", "cannot write there (Not a directory)")]:
        r = _run("plot", ies, "-o", str(out))
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and message in lines[0], (out, r.stderr)
    assert not (tmp_path / "noext.png").exists()
