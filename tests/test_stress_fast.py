"""Fast subset of the numerical stress sweep (benchmarks/stress.py): extreme roughness, IOR,
albedo, optical depth, HG g, microflake stddev and fibers along the normal, cos θ down to 1e-6,
16-layer stacks, textures with NaN/negative texels, furnace renders.

Every case must produce no NaN/Inf, no negative value and no energy gain (an albedo estimate above
1 by more than 3 standard errors, confirmed by an independent run with 4× the lanes); layered
walk-cap hits must stay a small fraction of the walks. Cases whose material type has not landed
are skipped with the loader's message.
"""
import pytest

from benchmarks import stress

LANES = 256


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    d = tmp_path_factory.mktemp("stress")
    stress.write_texture(d / "stress_texels.exr")
    stress.write_texture(d / "stress_texels_huge.exr", huge=True)
    return d


def _cases():
    from pathlib import Path
    tex = Path("stress_texels.exr")   # replaced by the fixture's absolute path in the test
    return [c for c in stress.all_cases(tex) if c.fast]


@pytest.mark.parametrize("case", _cases(), ids=lambda c: f"{c.family}:{c.name}")
def test_stress_case_has_no_failures(case, base):
    case = _with_texture(case, base)
    res = stress.run_case(case, base, stress.lanes_for(case, LANES), fast=True)
    if not res.available:
        pytest.skip(res.note)
    assert res.nan == 0, f"{case.name}: {res.nan} NaN/Inf values ({res.note})"
    assert res.neg == 0, f"{case.name}: {res.neg} negative values"
    assert res.gain == 0, f"{case.name}: energy gain confirmed in {res.gain} estimates (max albedo {res.max_albedo:.4f})"
    # Walk caps are a statistic, not an error, but must stay rare (bounded).
    if res.walks:
        assert res.cap <= max(5, 1e-3 * res.walks), f"{case.name}: {res.cap} walk-cap hits in {res.walks} walks"


def _with_texture(case, base):
    """Point texture references at the fixture's files."""
    import copy
    import json
    text = json.dumps(case.spec)
    if "stress_texels" not in text:
        return case
    text = text.replace('"stress_texels.exr"', json.dumps(str(base / "stress_texels.exr")))
    text = text.replace('"stress_texels_huge.exr"', json.dumps(str(base / "stress_texels_huge.exr")))
    out = copy.copy(case)
    out.spec = json.loads(text)
    return out


def test_the_sweep_detects_energy_gain(base):
    # A diffuse colour of 1.05 is legal in the schema but reflects 5 % more than it receives: the
    # detector must flag it (otherwise the zero counts above would mean nothing).
    case = stress.Case("material", "diffuse 1.05", {"type": "diffuse", "color": [1.05, 1.05, 1.05]})
    res = stress.run_case(case, base, LANES, fast=True)
    assert res.gain > 0
    # A lossy one must not be flagged.
    case = stress.Case("material", "diffuse 0.95", {"type": "diffuse", "color": [0.95, 0.95, 0.95]})
    assert stress.run_case(case, base, LANES, fast=True).gain == 0


def test_the_sweep_counts_nan_and_negative_values():
    import numpy as np
    assert stress._bad(np.array([1.0, np.nan, -np.inf, -2.0, 0.0])) == (2, 1)
