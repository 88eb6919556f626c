"""Ray visibility, light linking and shadow linking against Cycles, rendered side by side in bpy
(cases/visibility_cases.py). Each named region's mean must agree with Cycles within 2 % or 4
standard errors (σ from the pixel scatter of the difference image: both are Monte Carlo
estimates); each scene also checks that Cycles itself shows the effect (a region that a
feature darkens is far darker than its counterpart), so the comparison cannot pass with the
feature ignored by both, and that the add-on wrote the fields."""
from __future__ import annotations

import numpy as np
import pytest

from bpy_harness import backend_renders, requires_bpy, result_of, run_cases
from test_engine import channels_named, read_exr_parts

pytestmark = [pytest.mark.blender, pytest.mark.slow, requires_bpy,
              pytest.mark.skipif(not backend_renders(("diffuse", "conductor", "dielectric"),
                                                     ("point", "area"), ("constant",)),
                                 reason="the backend cannot render this scene")]

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
TOLERANCE = 0.02
K_SIGMA = 4.0
CASES = ["light_linking_pair", "shadow_linking_pair", "ray_types_pair"]


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    return run_cases("visibility_cases", CASES, tmp=tmp_path_factory.mktemp("visibility"), timeout=1500)


def region_rows(r):
    """name → (Cycles mean, Lamina mean, standard error of the difference)."""
    assert r["cycles_error"] is None and r["lamina_error"] is None, r
    cyc = channels_named(read_exr_parts(r["cycles"]), ["R", "G", "B"]).astype(np.float64) @ LUMINANCE
    lam = channels_named(read_exr_parts(r["lamina"]), ["R", "G", "B"]).astype(np.float64) @ LUMINANCE
    assert np.isfinite(lam).all() and cyc.shape == lam.shape
    h, w = cyc.shape
    half = r["half"]
    rows = {}
    for name, (x0, y0, x1, y1) in r["regions"].items():
        # Row 0 of the image is its top (+Y in the world seen from above).
        cols = slice(int(np.ceil((x0 + half) / (2 * half) * w)), int((x1 + half) / (2 * half) * w))
        lines = slice(int(np.ceil((half - y1) / (2 * half) * h)), int((half - y0) / (2 * half) * h))
        c, l = cyc[lines, cols].ravel(), lam[lines, cols].ravel()
        assert c.size >= 16, name
        diff = l - c
        rows[name] = (c.mean(), l.mean(), diff.std(ddof=1) / np.sqrt(diff.size))
    return rows


def report(rows):
    return "\n".join(f"  {n:20s} Cycles {c:.4f}  Lamina {l:.4f}  ratio {l / max(c, 1e-12):.4f}  "
                     f"z {(l - c) / max(se, 1e-12):+.2f}" for n, (c, l, se) in rows.items())


def agree(c, l, se):
    return abs(l - c) <= max(TOLERANCE * abs(c), K_SIGMA * se)


def check(r):
    rows = region_rows(r)
    text = report(rows)
    print(f"\nCycles {r['cycles_seconds']:.1f} s, Lamina {r['lamina_seconds']:.1f} s\n{text}")
    bad = [n for n, row in rows.items() if not agree(*row)]
    assert not bad, f"outside 2 % / 4σ of Cycles: {bad}\n{text}"
    return rows


def by_name(entries, name):
    return next(e for e in entries if e.get("_name") == name)


def test_light_linking_matches_cycles(pairs):
    r = result_of(pairs, "light_linking_pair")
    rows = check(r)
    cyc = {n: c for n, (c, _, _) in rows.items()}
    assert cyc["A"] < 0.2 * cyc["B"] and cyc["floor by C"] < 0.2 * cyc["C"], rows
    ex = r["exported"]
    assert by_name(ex["lights"], "Lamp")["light_linking"] == {"receivers": {"exclude": ["A"]}}
    assert by_name(ex["objects"], "Panel")["light_linking"] == {"receivers": {"include": ["C"]}}
    assert not any("linking" in n for n in ex["notes"]), ex["notes"]


def test_shadow_linking_matches_cycles(pairs):
    r = result_of(pairs, "shadow_linking_pair")
    rows = check(r)
    cyc = {n: c for n, (c, _, _) in rows.items()}
    assert cyc["under P"] < 0.8 * cyc["under Q"] and cyc["under P"] < 0.8 * cyc["under S"], rows
    assert cyc["under R"] > 1.2 * cyc["under P"], rows
    ex = r["exported"]
    assert by_name(ex["lights"], "Spot")["light_linking"] == {"blockers": {"include": ["P"]}}
    assert by_name(ex["lights"], "Panel")["light_linking"] == {"blockers": {"exclude": ["R"]}}
    assert by_name(ex["objects"], "S")["visible_shadow"] is False


def test_ray_visibility_matches_cycles(pairs):
    r = result_of(pairs, "ray_types_pair")
    rows = check(r)
    cyc = {n: c for n, (c, _, _) in rows.items()}
    assert cyc["matte, no diffuse"] < 0.8 * cyc["matte, no glossy"], rows
    assert cyc["metal, no glossy"] < 0.8 * cyc["metal, no diffuse"], rows
    assert cyc["glass over hidden"] < 0.2 * cyc["glass over shown"], rows
    ex = r["exported"]
    assert by_name(ex["objects"], "Panel0")["visible_diffuse"] is False
    assert by_name(ex["objects"], "Panel1")["visible_glossy"] is False
    assert by_name(ex["objects"], "Hidden")["visible_transmission"] is False
