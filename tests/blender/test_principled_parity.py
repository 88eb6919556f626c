"""Cycles parity of translated materials, rendered side by side in bpy (Cycles vs Lamina).

Principled BSDF combinations (base colour, roughness, IOR, coat, metallic 0.3, transmission 0.5,
metal, Specular IOR Level + Tint) and a Mix Shader of a Diffuse and a Glossy BSDF, one sphere each: each sphere's region mean must agree with
Cycles within 2 %, or within 4 standard errors where the noise is larger (σ estimated from the
pixel scatter of the difference image: both renders are Monte Carlo estimates).
"""
from __future__ import annotations

import numpy as np
import pytest

from bpy_harness import backend_renders, requires_bpy, result_of, run_cases
from test_engine import channels_named, read_exr_parts

pytestmark = [pytest.mark.blender, pytest.mark.slow, requires_bpy,
              pytest.mark.skipif(not backend_renders(("diffuse", "layered", "conductor", "dielectric"),
                                                     ("sun", "area"), ("constant",)),
                                 reason="the backend cannot render this scene")]

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
TOLERANCE = 0.02
K_SIGMA = 4.0


def region_ratios(r, names, cell):
    cyc = channels_named(read_exr_parts(r["cycles"]), ["R", "G", "B"]).astype(np.float64)
    lam = channels_named(read_exr_parts(r["lamina"]), ["R", "G", "B"]).astype(np.float64)
    assert np.isfinite(lam).all() and cyc.shape == lam.shape
    rows = []
    for i, name in enumerate(names):
        block = (slice(None), slice(i * cell, (i + 1) * cell))
        c, l = cyc[block] @ LUMINANCE, lam[block] @ LUMINANCE
        diff = (l - c).ravel()
        se = diff.std(ddof=1) / np.sqrt(diff.size) / max(c.mean(), 1e-9)
        rows.append((name, l.mean() / max(c.mean(), 1e-9), se, c.mean(), l.mean()))
    return rows


# Combinations a single Lamina stack does not reproduce within 2 % yet (figures in docs/blender.md):
# a coat's physical stack concentrates the base's light towards the normal (TIR inside the coat),
# so a front-lit coated sphere is brighter than Cycles' albedo-scaled coat although the albedo
# under uniform light matches (tests/test_principled_table.py). (A 50 % transmission, 0.46 before
# the Mix Shader, is now a mix of the glass and the opaque translation: 1.006 ± 0.007.)
KNOWN_GAPS = {"coat": "coat: BRDF shape differs from Cycles' albedo-scaled coat (+3.9 to +4.8 % measured)"}


@pytest.fixture(scope="module")
def principled_rows(tmp_path_factory):
    r = result_of(run_cases("parity_cases", ["principled_spheres"], tmp=tmp_path_factory.mktemp("parity"),
                            timeout=1500), "principled_spheres")
    assert r["cycles_error"] is None and r["lamina_error"] is None, r
    rows = region_ratios(r, r["names"], r["cell"])
    report = "\n".join(f"  {name:22s} Lamina/Cycles {ratio:.4f} ± {se:.4f}  (Cycles {c:.4f}, Lamina {l:.4f})"
                       for name, ratio, se, c, l in rows)
    print(f"\nPrincipled parity (Cycles {r['cycles_seconds']:.0f} s, Lamina {r['lamina_seconds']:.0f} s):\n{report}")
    return {name: (ratio, se) for name, ratio, se, _, _ in rows}, report


def within(ratio, se):
    return abs(ratio - 1) <= max(TOLERANCE, K_SIGMA * se)


def test_principled_combinations_match_cycles(principled_rows):
    rows, report = principled_rows
    checked = [name for name in rows if name not in KNOWN_GAPS]
    assert len(checked) >= 6
    bad = [name for name in checked if not within(*rows[name])]
    assert not bad, f"outside 2 % / 4σ: {bad}\n{report}"


@pytest.mark.parametrize("name", sorted(KNOWN_GAPS))
def test_known_gaps_are_still_gaps(principled_rows, name):
    """Strict expected failures: the day one of these matches, this fails and the entry goes."""
    rows, report = principled_rows
    if within(*rows[name]):
        pytest.fail(f"{name} now matches Cycles: remove it from KNOWN_GAPS\n{report}")
    pytest.xfail(KNOWN_GAPS[name])


def test_one_and_two_sided_emission_match_cycles(tmp_path):
    """Three emissive panels over a floor (two-sided, front-only seen from the back, front-only
    facing the camera): the panels and the floor under them (the upper two of 3 × 6 regions)
    within 2 % / 4σ of Cycles (one-sided there through a Mix Shader on Backfacing). The nearest
    row of floor, lit at grazing angles, is printed, not checked: there Lamina differs from Cycles
    by ~2 % already with two-sided emitters only (up to 14 % with a two-sided panel whose back
    faces that floor; measured, a renderer issue outside the add-on, see docs/blender.md)."""
    r = result_of(run_cases("parity_cases", ["emission_sides"], tmp=tmp_path, timeout=900), "emission_sides")
    assert r["cycles_error"] is None and r["lamina_error"] is None, r
    cyc = channels_named(read_exr_parts(r["cycles"]), ["R", "G", "B"]).astype(np.float64) @ LUMINANCE
    lam = channels_named(read_exr_parts(r["lamina"]), ["R", "G", "B"]).astype(np.float64) @ LUMINANCE
    h, w = cyc.shape
    lines, bad = [], []
    for i in range(3):
        for j in range(6):
            block = (slice(i * h // 3, (i + 1) * h // 3), slice(j * w // 6, (j + 1) * w // 6))
            c, l = cyc[block], lam[block]
            diff = (l - c).ravel()
            se = diff.std(ddof=1) / np.sqrt(diff.size) / c.mean()
            ratio = l.mean() / c.mean()
            ok = abs(ratio - 1) <= max(TOLERANCE, K_SIGMA * se)
            lines.append(f"  region {i},{j}: Cycles {c.mean():.4f} Lamina/Cycles {ratio:.4f} ± {se:.4f}"
                         f"{'' if ok else (' <--' if i < 2 else ' (not checked)')}")
            if not ok and i < 2:
                bad.append((i, j))
    print("\nEmission parity:\n" + "\n".join(lines))
    assert not bad, "\n".join(lines)
    # The front-only panel seen from its back is black in both renders (its regions are dark).
    back = (slice(0, h // 3), slice(w // 2 - w // 12, w // 2 + w // 12))
    assert lam[back].min() < 0.05 * lam.max() and cyc[back].min() < 0.05 * cyc.max()


@pytest.mark.parametrize("case", ["normal_mapped_planes", "bumped_planes"])
def test_normal_mapped_and_bumped_planes_match_cycles(tmp_path, case):
    """A Normal Map node (tangent space, image texture, Strength) or a Bump node (image height,
    Distance, Strength, Invert) on a Diffuse BSDF: three planes under a sun (none, tilted towards
    the sun, tilted sideways at strength 0.6), each plane's central region within 2 % / 4σ of
    Cycles; the maps change the brightness by far more than the tolerance, so a map that is
    ignored, read in the wrong frame or with the wrong sign or scale fails."""
    r = result_of(run_cases("parity_cases", [case], tmp=tmp_path, timeout=900), case)
    assert r["cycles_error"] is None and r["lamina_error"] is None, r
    cyc = channels_named(read_exr_parts(r["cycles"]), ["R", "G", "B"]).astype(np.float64) @ LUMINANCE
    lam = channels_named(read_exr_parts(r["lamina"]), ["R", "G", "B"]).astype(np.float64) @ LUMINANCE
    h, w = cyc.shape
    rows, lines = [], []
    for i, name in enumerate(r["names"]):
        block = (slice(h // 2 - 5, h // 2 + 5), slice(i * w // 3 + w // 12, (i + 1) * w // 3 - w // 12))
        c, l = cyc[block], lam[block]
        diff = (l - c).ravel()
        se = diff.std(ddof=1) / np.sqrt(diff.size) / c.mean()
        rows.append((name, l.mean() / c.mean(), se, c.mean()))
        lines.append(f"  {name:28s} Lamina/Cycles {l.mean() / c.mean():.4f} ± {se:.4f} (Cycles {c.mean():.4f})")
    print(f"\n{case}:\n" + "\n".join(lines))
    assert all(within(ratio, se) for _, ratio, se, _ in rows), "\n".join(lines)
    flat, toward, sideways = (c for *_, c in rows)
    assert toward > 1.15 * flat and sideways < 0.97 * flat       # the maps matter in Cycles too


def test_motion_blurred_cube_matches_cycles(tmp_path):
    """A cube sliding and turning during the shutter: 8 × 8-pixel blocks over the blur (where the
    cube covers a pixel part of the time) within 2 % / 4σ of Cycles; without motion blur the
    blocks at the blur's ends would be all cube or all floor."""
    r = result_of(run_cases("parity_cases", ["motion_blurred_cube"], tmp=tmp_path, timeout=900),
                  "motion_blurred_cube")
    assert r["cycles_error"] is None and r["lamina_error"] is None, r
    cyc = channels_named(read_exr_parts(r["cycles"]), ["R", "G", "B"]).astype(np.float64)
    lam = channels_named(read_exr_parts(r["lamina"]), ["R", "G", "B"]).astype(np.float64)
    red_c, red_l = cyc[..., 0] - cyc[..., 1], lam[..., 0] - lam[..., 1]    # the cube's share
    lines, bad = [], []
    for y in range(8, 40, 8):
        for x in range(8, 56, 8):
            c, l = red_c[y:y + 8, x:x + 8], red_l[y:y + 8, x:x + 8]
            if c.mean() < 0.02:
                continue                                        # floor and world only
            diff = (l - c).ravel()
            se = diff.std(ddof=1) / np.sqrt(diff.size) / c.mean()
            ratio = l.mean() / c.mean()
            lines.append(f"  block ({x:2d}, {y:2d}) Lamina/Cycles {ratio:.4f} ± {se:.4f} (Cycles {c.mean():.4f})")
            if not within(ratio, se):
                bad.append(lines[-1])
    print("\nMotion-blurred cube (red minus green):\n" + "\n".join(lines))
    assert len(lines) >= 6
    assert not bad, "\n".join(bad)
    # The blur is there, in both: on the rows through the cube, pixels the cube covers for part
    # of the shutter (red share between 15 % and 85 % of the full cube's) span ~2 × 7 pixels;
    # a sharp silhouette leaves ~2 × 1 (its antialiasing).
    for img in (red_c, red_l):
        rows = img[20:28]
        full = np.percentile(rows, 99)
        partial = ((rows > 0.15 * full) & (rows < 0.85 * full)).sum(axis=1)
        assert np.median(partial) >= 8, partial
    assert r["motion_steps"] == {"Cube": 5, "Floor": 0}          # only what moves
    assert r["frame_after"] == [5, 0.0]                           # the frame is restored
