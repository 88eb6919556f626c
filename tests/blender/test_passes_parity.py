"""Data passes and stereo / multi-view: Lamina against Cycles, rendered side by side in bpy.

The passes are deterministic functions of where a camera sample lands (no light transport), so
the two renderers differ only through their sub-pixel sample positions (both: Blackman-Harris
filter, width 1.5 px, importance sampled). Hence:
* away from edges (pixels whose 5 × 5 neighbourhood has one Object Index in Cycles: every
  sample of the filter, ±2 px at most, saw the same surface) the index passes agree exactly and
  the other passes' region means agree within 4 standard errors of the per-pixel difference
  (the samples' jitter), plus 1e-4 of the pass's range for float32 storage;
* Depth and the indices are sample-0 values in both: never fractional at edges;
* every stereo eye (off-axis, toe-in, parallel convergence; pivot at the centre) and multi-view
  camera matches Cycles' view of it (index passes equal away from edges, Depth and Position
  region means within 4σ), and the two views differ.
"""
from __future__ import annotations

import numpy as np
import pytest

from bpy_harness import backend_renders, requires_bpy, result_of, run_cases
from test_engine import channels_named, read_exr_parts

pytestmark = [pytest.mark.blender, requires_bpy,
              pytest.mark.skipif(not backend_renders(("diffuse",), ("sun",), ("constant",)),
                                 reason="the backend cannot render this scene")]

K_SIGMA = 4.0
BLOCKS = 4
CHANNELS = {"Depth": ["Z"], "Mist": ["Z"], "Normal": ["X", "Y", "Z"], "Position": ["X", "Y", "Z"],
            "UV": ["U", "V", "A"], "Object Index": ["X"], "Material Index": ["X"]}
INDICES = {0.0, 2.0, 4.0}          # world, ball, floor
MATERIALS = {0.0, 5.0, 9.0}


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    r = run_cases("passes_cases", ["data_passes", "stereo", "stereo_toe", "stereo_parallel", "multiview"],
                  tmp=tmp_path_factory.mktemp("passes"), timeout=900)
    return r


def _passes(path):
    parts = read_exr_parts(path)
    return {name: channels_named(parts, [f"{name}.{c}" for c in chans]).astype(np.float64)
            for name, chans in CHANNELS.items()}


def _uniform(index: np.ndarray, radius: int = 2) -> np.ndarray:
    """Pixels whose (2r+1)² neighbourhood holds one value (edges of the image excluded)."""
    h, w = index.shape
    out = np.zeros((h, w), bool)
    for y in range(radius, h - radius):
        for x in range(radius, w - radius):
            block = index[y - radius:y + radius + 1, x - radius:x + radius + 1]
            out[y, x] = block.min() == block.max()
    return out


def _region_z(lam, cyc, mask):
    """Worst |mean difference| / (4σ + float floor) over BLOCKS² regions of the masked pixels."""
    h, w = mask.shape
    worst = 0.0
    rows = []
    for by in range(BLOCKS):
        for bx in range(BLOCKS):
            ys = slice(by * h // BLOCKS, (by + 1) * h // BLOCKS)
            xs = slice(bx * w // BLOCKS, (bx + 1) * w // BLOCKS)
            m = mask[ys, xs]
            if m.sum() < 8:
                continue
            d = (lam[ys, xs][m] - cyc[ys, xs][m])
            se = d.std(ddof=1) / np.sqrt(d.size)
            scale = max(np.abs(cyc[ys, xs][m]).max(), 1.0)
            ratio = abs(d.mean()) / (K_SIGMA * se + 1e-4 * scale)
            rows.append((by, bx, d.mean(), se))
            worst = max(worst, ratio)
    return worst, rows


def _compare(cyc_path, lam_path):
    cyc, lam = _passes(cyc_path), _passes(lam_path)
    assert cyc["Depth"].shape == lam["Depth"].shape
    index = cyc["Object Index"][..., 0]
    mask = _uniform(index)
    assert mask.mean() > 0.5
    report = {}
    # Index passes: exactly equal where the neighbourhood is uniform; whole values everywhere.
    for name, allowed in (("Object Index", INDICES), ("Material Index", MATERIALS)):
        assert set(np.unique(lam[name])) <= allowed, (name, np.unique(lam[name]))
        assert set(np.unique(cyc[name])) <= allowed
        np.testing.assert_array_equal(lam[name][mask], cyc[name][mask], err_msg=name)
    # Depth: 1e10 on the world in both; on surfaces region means (sample 0's jitter).
    world = mask & (index == 0)
    assert np.all(lam["Depth"][world] == cyc["Depth"][world]) and np.all(cyc["Depth"][world] == 1e10)
    surface = mask & (index > 0)
    for name in ("Depth", "Mist", "Normal", "Position", "UV"):
        for c in range(lam[name].shape[2]):
            worst, rows = _region_z(lam[name][..., c], cyc[name][..., c], surface if name == "Depth" else mask)
            report[f"{name}.{CHANNELS[name][c]}"] = (worst, rows)
    return report, cyc, lam


def _check(report):
    bad = {k: v for k, v in report.items() if v[0] > 1.0}
    text = "\n".join(f"  {k}: worst |Δ|/(4σ+floor) {v[0]:.2f}" for k, v in report.items())
    print(f"\nLamina vs Cycles, data passes:\n{text}")
    assert not bad, f"regions outside 4σ:\n{text}\n{ {k: v[1] for k, v in bad.items()} }"


def test_data_passes_match_cycles(renders):
    r = result_of(renders, "data_passes")
    assert r["cycles_error"] is None and r["lamina_error"] is None, r
    report, cyc, lam = _compare(r["cycles"], r["lamina"])
    _check(report)
    # The averaged passes are averages at edges (UV's third channel is the UV-mapped coverage),
    # in both renderers.
    for img in (cyc, lam):
        a = img["UV"][..., 2]
        assert np.any((a > 0.05) & (a < 0.95))


def _eyes(r):
    stem_c, stem_l = r["cycles"][:-4], r["lamina"][:-4]
    return [(f"{stem_c}_{s}.exr", f"{stem_l}_{s}.exr") for s in ("L", "R")]


@pytest.mark.parametrize("case", ["stereo", "stereo_toe", "stereo_parallel", "multiview"])
def test_each_view_renders_its_own_camera(renders, case):
    r = result_of(renders, case)
    assert r["cycles_error"] is None and r["lamina_error"] is None, r
    indices = []
    for cyc_path, lam_path in _eyes(r):
        report, cyc, lam = _compare(cyc_path, lam_path)
        _check({k: v for k, v in report.items() if k.startswith(("Depth", "Position"))})
        indices.append(lam["Object Index"][..., 0])
    # The two views see the scene from different places: many pixels change object.
    changed = np.mean(indices[0] != indices[1])
    assert changed > 0.02, changed
