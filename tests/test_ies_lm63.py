"""LM-63 reader: every real file parses and matches the README index; malformed files fail clearly."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from backend.errors import LaminaError
from backend.ies.lm63 import LM63Error, parse_lm63, read_lm63, to_cycles_frame
from backend.ies.profile import IESProfile
from ies_reference import parse_readme_table

IES_DIR = Path(__file__).parent / "data" / "ies"
README = parse_readme_table(IES_DIR / "README.md")
FILES = sorted(IES_DIR.glob("*.ies"))


def _row_id(row):
    return row["file"].strip("`")


def test_readme_lists_every_file():
    assert sorted(_row_id(r) for r in README) == sorted(p.name for p in FILES)
    assert len(FILES) == 14


def _range(text):
    """'19 (0..90)' → (19, 0.0, 90.0)."""
    m = re.match(r"(\d+) \((-?[\d.]+)\.\.(-?[\d.]+)\)", text)
    return int(m.group(1)), float(m.group(2)), float(m.group(3))


@pytest.mark.parametrize("row", README, ids=_row_id)
def test_file_matches_readme(row):
    f = read_lm63(IES_DIR / _row_id(row))
    # version
    if "no version line" in row["version"]:
        assert f.version == "LM-63-1986" and f.version_line is None
    else:
        assert f.version_line == row["version"]
    assert f.tilt == row["TILT"]
    assert f.type_letter == row["type"]
    nv, v0, v1 = _range(row["#V (range)"])
    nh, h0, h1 = _range(row["#H (range)"])
    assert (f.vertical_angles.size, f.vertical_angles[0], f.vertical_angles[-1]) == (nv, v0, v1)
    assert (f.horizontal_angles.size, f.horizontal_angles[0], f.horizontal_angles[-1]) == (nh, h0, h1)
    assert f.candela.shape == (nh, nv)
    # symmetry: README words → our names; type B files state the H range instead
    sym = row["symmetry"]
    if sym.startswith("type B"):
        expected = "bilateral" if h0 == 0 else "none"
    else:
        expected = {"axial": "axial", "quadrilateral": "quadrilateral", "bilateral": "bilateral",
                    "none": "none"}[sym.split()[0]]
    assert f.symmetry == expected
    # lamps × lumens
    lamps, lm = [s.strip() for s in row["lamps x lm/lamp"].split("x", 1)]
    assert f.lamps == int(lamps)
    if lm.startswith("absolute"):
        assert f.lumens_per_lamp == -1 and f.stated_lumens is None
    else:
        assert f.lumens_per_lamp == pytest.approx(float(lm))
    # multiplier (README rounds to 6 significant digits), ballast and ballast-lamp factors
    m = re.match(r"([\d.]+) \(x ([\d.]+) x ([\d.]+)\)", row["cd multiplier (x ballast x b-l factor)"])
    assert f.multiplier == pytest.approx(float(m.group(1)), rel=5e-6)
    assert f.ballast_factor == float(m.group(2)) and f.ballast_lamp_factor == float(m.group(3))
    assert {"m": 2, "ft": 1}[row["units"]] == f.units
    # peak candela (README rounds to integers) of the table with the multiplier applied
    assert abs(float(np.max(f.candela)) * f.factor - float(row["peak cd"])) <= 0.5


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_every_file_expands_to_a_valid_table(path):
    p = IESProfile.from_file(path)
    assert np.all(np.diff(p.h_deg) > 0) and np.all(np.diff(p.v_deg) > 0)
    assert p.candela.shape == (p.h_deg.size, p.v_deg.size)
    assert np.all(np.isfinite(p.candela)) and np.all(p.candela >= 0)
    if p.source.photometric_type == 1:
        assert p.h_deg[0] == 0.0 and p.h_deg[-1] == 360.0
        if p.source.symmetry != "none":   # expanded tables wrap seamlessly; measured 360° columns
            np.testing.assert_array_equal(p.candela[0], p.candela[-1])   # are used as written
    assert p.flux > 0 and p.peak["candela"] > 0   # never a silent black or isotropic light


def test_keywords_more_chains_empty_and_non_ascii():
    f = read_lm63(IES_DIR / "hew_bollard_v0_180_lm02.ies")
    assert f.keyword("LUMINAIRE").split("\n") == [
        '1/100W CLEAR ED17 LAMP 6"DIA 38.25"TALL WHITE BOLLARD',
        '4.5"DIA SPECULAR CONE REFLECTOR w/5.875"TALL ACRYLIC',
        "CYLINDER LENS"]
    assert "MORE" not in f.keyword_dict()

    g = read_lm63(IES_DIR / "rab_asym360_45deg_lm02.ies")
    assert g.keyword("TEST") == "" and g.keyword("NEARFIELD") == ""   # empty keywords kept
    assert g.keyword("LAMPPOSITION") == "0,0"

    e = read_lm63(IES_DIR / "erco_defined_spot_lm95.ies")   # Latin-1 degree sign (0xB0)
    assert e.keyword("LAMPCAT") == "HIPAR-L30 35W 30°"
    # "[LUMCAT]\xa0BAYLED78W...": the Latin-1 no-break space separates key and value like a space
    n = read_lm63(IES_DIR / "rab_bayled78_bilateral180_nonascii_lm02.ies")
    assert n.keyword("LUMCAT") == "BAYLED78W+GDBAYLED78FP (with standoffs installed)"
    assert n.keyword("_ABSOLUTELUMENS") == "5822"
    assert len(n.keyword_dict()["_SEARCH_APPLICATION"]) == 2   # repeated keywords all kept

    d = read_lm63(IES_DIR / "rab_dled6_24lamps_axial_lm02.ies")
    assert [k for k, _ in d.keywords].count("OTHER") == 3
    assert d.keyword("_NOTE").endswith("\nVOLTAGE (120VAC, 60Hz) TO THE LED ASSEMBLY.")


def test_one_value_per_line_with_end_and_ctrl_z():
    path = IES_DIR / "erco_double_focus_lm86_onevalueperline.ies"
    raw = path.read_bytes()
    assert raw.rstrip().endswith(b"END\r\n\x1a") or raw.endswith(b"\x1a")   # the oddities are there
    f = read_lm63(path)
    assert f.version == "LM-63-1986" and "light output ratio: 0.5912" in f.header_lines
    assert f.candela.shape == (1, 19)


def test_tilt_include_block_parsed_not_applied():
    f = read_lm63(IES_DIR / "eulumdat_tilt_include_synthetic_lm02.ies")
    assert f.tilt == "INCLUDE" and f.tilt_block.geometry == 1
    np.testing.assert_array_equal(f.tilt_block.angles, [0, 45, 90, 180])
    np.testing.assert_array_equal(f.tilt_block.factors, [1.0, 0.9, 0.8, 1.0])
    np.testing.assert_array_equal(f.candela[0], [1000, 900, 700, 400, 100])   # not scaled by tilt
    # A keyword value containing "TILT=INCLUDE" is not the TILT line.
    assert f.keyword("LUMINAIRE") == "TILT=INCLUDE Test Fixture"


# ------------------------------------------------------------------ small synthetic files

GOOD = """IESNA:LM-63-2002
[TEST] synthetic
[MANUFAC] Lamina
TILT=NONE
1 1000 1 5 3 1 2 0 0 0
1 1 10
0 22.5 45 67.5 90
0 45 90
100 90 70 40 10
100 80 60 30 5
100 70 50 20 0
"""
#  line numbers:   1 version, 2-3 keywords, 4 TILT, 5-6 header, 7 V angles, 8 H angles, 9-11 table


def test_synthetic_good_file():
    f = parse_lm63(GOOD, name="good.ies")
    assert f.symmetry == "quadrilateral"
    assert f.candela.shape == (3, 5)
    h, v, t = to_cycles_frame(f)
    np.testing.assert_array_equal(h, [0, 45, 90, 135, 180, 225, 270, 315, 360])


def _err(text, name="bad.ies"):
    with pytest.raises(LM63Error) as info:
        parse_lm63(text, name=name)
    msg = str(info.value)
    assert isinstance(info.value, LaminaError)
    assert msg.startswith(f"{name}: ") and "\n" not in msg
    return info.value


def test_truncated():
    e = _err("\n".join(GOOD.splitlines()[:10]) + "\n")     # last candela row missing
    assert e.line == 10 and "unexpected end of file" in e.message
    assert "expected 15 candela values" in e.message and "found only 10" in e.message
    e = _err("\n".join(GOOD.splitlines()[:5]) + "\n")      # stops after the first header line
    assert e.line == 5 and "ballast factor" in e.message


def test_wrong_counts():
    too_many_v = GOOD.replace("1 1000 1 5 3", "1 1000 1 6 3")   # 6 vertical angles declared
    e = _err(too_many_v)
    assert e.line == 8 and "increase strictly" in e.message and "wrong angle counts" in e.message
    too_few_h = GOOD.replace("1 1000 1 5 3", "1 1000 1 5 2")    # 2 horizontal angles declared
    e = _err(too_few_h)
    assert "increase strictly" in e.message or "unexpected number" in e.message
    # counts that happen to consume consistent angles but leave numbers over
    extra = GOOD + "5 5 5 5 5\n"
    e = _err(extra)
    assert e.line == 12 and "unexpected number '5'" in e.message and "5 vertical × 3 horizontal" in e.message


def test_non_numeric():
    e = _err(GOOD.replace("100 80 60 30 5", "100 80 6O 30 5"))
    assert e.line == 10 and "got '6O'" in e.message and "candela value 8 of 15" in e.message
    e = _err(GOOD.replace("1 1000 1 5 3 1 2", "1 1000 x 5 3 1 2"))
    assert e.line == 5 and "candela multiplier" in e.message
    e = _err(GOOD.replace("0 45 90\n", "0 45 nan\n"))
    assert e.line == 8 and "'nan'" in e.message


def test_missing_tilt():
    e = _err(GOOD.replace("TILT=NONE\n", ""))
    assert e.line == 4 and "TILT=NONE" in e.message and "before the photometric data" in e.message
    e = _err("IESNA:LM-63-2002\n[TEST] x\n")
    assert "without a 'TILT=' line" in e.message


def test_non_monotonic_angles():
    e = _err(GOOD.replace("0 22.5 45 67.5 90", "0 22.5 67.5 45 90"))
    assert e.line == 7 and "vertical angles must increase strictly" in e.message and "45° after 67.5°" in e.message
    e = _err(GOOD.replace("0 45 90\n", "0 90 45\n"))
    assert e.line == 8 and "horizontal angles" in e.message


def test_other_header_errors():
    assert "photometric type" in _err(GOOD.replace("1 1000 1 5 3 1 2", "1 1000 1 5 3 4 2")).message
    assert "at least 2 vertical" in _err(GOOD.replace("1 1000 1 5 3 1 2", "1 1000 1 1 3 1 2")).message
    assert "candela multiplier > 0" in _err(GOOD.replace("1 1000 1 5 3", "1 1000 0 5 3")).message
    assert "ballast factor > 0" in _err(GOOD.replace("1 1 10", "0 1 10")).message
    e = _err(GOOD.replace("100 70 50 20 0", "100 70 -50 20 0"))
    assert e.line == 11 and ">= 0" in e.message
    e = _err(GOOD.replace("0 22.5 45 67.5 90", "0 22.5 45 67.5 200"))
    assert e.line == 7 and "0..180" in e.message
    assert "empty file" in _err("  \n\n").message


def test_unrecognised_horizontal_range_is_an_error():
    bad = GOOD.replace("0 45 90\n", "0 45 100\n")   # 0..100: no LM-63 symmetry
    f = parse_lm63(bad, name="odd.ies")
    with pytest.raises(LM63Error, match="odd.ies: .*match no LM-63 symmetry"):
        IESProfile(f)


def test_missing_360_column_added_when_spacing_shows_it():
    text = GOOD.replace("1 1000 1 5 3", "1 1000 1 5 4").replace("0 45 90\n", "0 90 180 270\n") \
        + "100 60 40 20 1\n"
    p = IESProfile.from_text(text)
    np.testing.assert_array_equal(p.h_deg, [0, 90, 180, 270, 360])
    np.testing.assert_array_equal(p.candela[-1], p.candela[0])


def test_read_errors():
    with pytest.raises(LaminaError, match="nope.ies: IES file not found"):
        read_lm63(IES_DIR / "nope.ies")


def test_tilt_other_file_and_formats(tmp_path):
    text = GOOD.replace("TILT=NONE", "TILT=lamp.tlt").replace("IESNA:LM-63-2002", "IES:LM-63-2019")
    f = parse_lm63(text)
    assert f.version == "LM-63-2019" and f.tilt == "lamp.tlt" and "ignored" in f.warnings[0]
    f91 = parse_lm63(GOOD.replace("IESNA:LM-63-2002", "IESNA91"))
    assert f91.version == "LM-63-1991"
    # comma separators, CRLF, tabs, a UTF-8 BOM and Fortran-style numbers are all fine
    messy = ("\ufeff" + GOOD).replace("\n", "\r\n").replace("0 22.5 45 67.5 90", "0.,22.5,\t45., 67.50 ,.9E2")
    g = parse_lm63(messy.encode("utf-8"))
    np.testing.assert_array_equal(g.vertical_angles, [0, 22.5, 45, 67.5, 90])
