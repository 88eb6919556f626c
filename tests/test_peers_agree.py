"""The Lamina-vs-Cycles benchmark's own machinery, without rendering: the region agreement check
(it must pass images of one distribution and fail a 1 % darker one), the scene-derived regions,
the equal-error interpolation and the converter's refusals. Cycles itself: test_peers_cycles.py."""
import copy
import math

import numpy as np
import pytest

from benchmarks.peers import agree, convert, metrics
from benchmarks.peers.scenes import PEER_SCENES, cornell, furnace

K = agree.K_SIGMA


def _synthetic(seed: int, darker: float = 1.0, rel_sigma: float = 0.02, n_renders: int = 4):
    """A smooth 'true' image with six regions; image A with a known per-pixel variance (as
    Lamina's film gives it), image B as the mean of ``n_renders`` noisy renders (as Cycles'
    split reference), both unbiased estimates of the truth (A optionally scaled by ``darker``)."""
    rng = np.random.default_rng(seed)
    h = w = 48
    yy, xx = np.mgrid[0:h, 0:w]
    truth = (0.5 + 0.4 * np.sin(xx / 9.0) * np.cos(yy / 13.0))[..., None] * np.array([1.0, 0.8, 0.6])
    lab = (yy * 2 // h) * 3 + (xx * 3 // w)                     # 2 × 3 blocks of 384 pixels
    names = [f"r{i}" for i in range(6)]
    sa = rel_sigma * truth
    a = darker * (truth + rng.normal(size=truth.shape) * sa)
    var_a = (darker * sa) ** 2
    renders = [truth + rng.normal(size=truth.shape) * rel_sigma * truth * math.sqrt(n_renders) for _ in range(n_renders)]
    b, var_b = agree.split_variance(renders)
    return a, var_a, b, var_b, agree.regions(lab, names, grid=1, min_pixels=24, whole=False)


def test_same_distribution_passes_and_one_percent_darker_fails():
    # With k = 4 and 18 tests per image a false alarm has probability ~1e-3 per image: all 20
    # independent pairs must pass. The same pairs with A 1 % darker are ~10 σ off in every region:
    # all must fail (the check can fail, and does so for the smallest error the issue names).
    passes = fails = 0
    for seed in range(20):
        a, va, b, vb, regs = _synthetic(seed)
        assert len(regs) == 6
        passes += agree.verdict(agree.check(a, va, b, vb, regs))["ok"]
        a, va, b, vb, regs = _synthetic(seed, darker=0.99)
        fails += not agree.verdict(agree.check(a, va, b, vb, regs))["ok"]
    assert passes == 20
    assert fails == 20


def test_standard_errors_are_calibrated():
    # The z scores of many independent region comparisons must have unit variance (a check
    # that over- or under-estimates σ would pass too much or fail too often).
    z = []
    for seed in range(40):
        a, va, b, vb, regs = _synthetic(100 + seed)
        z += [r.z for r in agree.check(a, va, b, vb, regs)]
    z = np.concatenate(z)
    n = z.size                                                   # 40 × 6 × 3 = 720
    # Var of the sample variance of n standard normals ≈ 2/n; the split estimate of B's variance
    # has only 3 degrees of freedom per pixel but is summed over 384 pixels per region.
    assert abs(z.var() - 1.0) < 4 * math.sqrt(2 / n)
    assert abs(z.mean()) < 4 / math.sqrt(n)


def test_a_region_without_noise_fails_on_any_difference():
    a = np.ones((8, 8, 3))
    regs = [("all", np.ones((8, 8), bool))]
    assert agree.verdict(agree.check(a, 0 * a, a.copy(), 0 * a, regs))["ok"]
    assert not agree.verdict(agree.check(a * (1 - 1e-6), 0 * a, a, 0 * a, regs))["ok"]


def test_regions_cut_large_labels_and_merge_small_tiles():
    lab = np.zeros((30, 30), int)
    lab[:, 20:] = 1                          # label 1: 30 × 10 = 300 pixels, label 0: 600
    lab[0, 0] = 2                            # a one-pixel label: dropped
    regs = agree.regions(lab, ["big", "small", "dot"], grid=3, min_pixels=24)
    assert regs[0][0] == "whole image" and regs[0][1].all()
    regs = regs[1:]
    names = [n for n, _ in regs]
    assert "dot" not in " ".join(names)
    covered = np.zeros_like(lab, dtype=int)
    for _, m in regs:
        covered += m
    assert covered.max() == 1                # regions never overlap
    assert covered[lab == 0].sum() == (lab == 0).sum() and covered[lab == 1].sum() == 300
    assert all(m.sum() >= 24 for _, m in regs)
    assert sum(n.startswith("big [") for n in names) >= 6


def test_labels_follow_the_scene():
    from backend.scene.loader import load_scene_data
    data = cornell(96)
    s = load_scene_data(copy.deepcopy(data))
    lab, names = agree.labels(data, s.soup.vertices, s.soup.object_id)
    assert lab.shape == (96, 96)
    assert names[lab[40, 48]] == "back wall"                  # the camera looks at the back wall
    assert names[lab[50, 3]] == "red wall" and names[lab[50, 92]] == "green wall"
    assert names[lab[95, 48]] == "floor" and names[lab[2, 20]] == "ceiling"
    light = names.index("light 0 (seen directly)")
    rows, cols = np.nonzero(lab == light)
    assert rows.size > 20 and rows.max() < 12 and abs(cols.mean() - 47.5) < 1.0   # top centre
    assert (lab == names.index("edges")).any()
    # The filter support sets the edge band: a wider filter makes more pixels straddle outlines.
    lab_wide, _ = agree.labels(data, s.soup.vertices, s.soup.object_id, half_width=2.0)
    assert (lab_wide == names.index("edges")).sum() > (lab == names.index("edges")).sum()


def test_error_removes_the_reference_noise():
    rng = np.random.default_rng(5)
    truth = rng.random((100, 100, 3)) + 0.5
    s_ref, s_img = 0.03, 0.1
    ref = truth + rng.normal(0, s_ref, truth.shape)
    img = truth + rng.normal(0, s_img, truth.shape)
    m = metrics.error(img, ref, np.full(truth.shape, s_ref ** 2))
    se = math.sqrt(2 * (s_img ** 2 + s_ref ** 2) ** 2 / truth.size)
    assert abs(m["mse"] - s_img ** 2) < 4 * se
    assert math.isclose(m["rel_rmse"], m["rmse"] / ref.mean())


def test_equal_error_interpolation_and_extrapolation_flag():
    spp = [1, 2, 4, 8, 16]
    err = [2.0 * s ** -0.5 for s in spp]
    x, extra = metrics.at_error(spp, err, 2.0 / math.sqrt(6.0))
    assert math.isclose(x, 6.0, rel_tol=1e-12) and not extra
    x, extra = metrics.at_error(spp, err, 2.0 / 8.0)            # beyond the measured range
    assert math.isclose(x, 64.0, rel_tol=1e-9) and extra
    t = metrics.targets([1.0, 0.5, 0.25], [0.6, 0.3, 0.1], n=3)
    assert all(0.25 < v < 0.6 for v in t) and t == sorted(t)
    c = metrics.cost([{"spp": s, "cpu": 0.5 + 0.01 * s} for s in spp], pixels=10_000)
    assert math.isclose(c["t0"], 0.5) and math.isclose(c["us_per_px_sample"], 1.0)


def test_converter_refuses_what_it_cannot_make_equal(tmp_path):
    base = furnace(8)

    def with_material(m):
        d = copy.deepcopy(base)
        d["materials"]["gold"] = m
        return d

    for bad in ({"type": "conductor", "metal": "Au"},
                {**base["materials"]["gold"], "distribution": "beckmann"},
                {**base["materials"]["gold"], "masking": "separable"},
                {"type": "dielectric", "ior": 1.5, "roughness": 0.1, "roughness_v": 0.2},
                {"type": "diffuse", "color": [1, 1, 1], "emission": [1, 1, 1]},
                {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5}, {"type": "conductor", "metal": "Cu"}],
                 "media": [{"sigma_t": 0}]}):
        with pytest.raises(convert.Unsupported):
            convert.prepare(with_material(bad), tmp_path / "bad")
    d = copy.deepcopy(base)
    d["lights"] = [{"type": "area", "to_world": np.eye(4).tolist(), "power": 1, "cutoff_angle": 30}]
    with pytest.raises(convert.Unsupported):
        convert.prepare(d, tmp_path / "bad")


def test_converter_passes_the_loaders_triangles_and_filter(tmp_path):
    import json

    from backend.scene.loader import load_scene_data
    assert convert.cycles_filter({"type": "blackman-harris", "width": 3.0}) == ("BLACKMAN_HARRIS", 3.0)
    assert convert.cycles_filter({"type": "gaussian", "width": 1.5}) == ("GAUSSIAN", 1.5)
    assert convert.cycles_filter({"type": "box", "width": 1.0}) == ("BOX", 1.0)
    for sc in PEER_SCENES:
        data = sc.build(16)
        job = json.loads(convert.prepare(data, tmp_path / sc.name, principled=sc.principled).read_text())
        geo = np.load(tmp_path / sc.name / "geometry.npz")
        soup = load_scene_data(copy.deepcopy(data)).soup
        assert sum(geo[f"o{o['index']}_pos"].shape[0] for o in job["objects"]) == soup.count
        for o in job["objects"]:
            np.testing.assert_array_equal(geo[f"o{o['index']}_pos"], soup.vertices[soup.object_id == o["index"]])
        assert job["cycles_filter"] == ["BLACKMAN_HARRIS", 1.5]


def test_command_line_refuses_contradictions(tmp_path, capsys):
    from benchmarks.__main__ import main
    with pytest.raises(SystemExit) as e:
        main(["peers", "--only", "tve", "--out", str(tmp_path)])
    assert e.value.code == 2 and "alone" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["peers", "--peer-scenes", "cornell,nope", "--out", str(tmp_path)])
    assert e.value.code == 2 and "nope" in capsys.readouterr().err


def test_principled_materials_reach_the_job_and_lamina_gets_the_addons_export(tmp_path):
    import json

    from benchmarks.peers.scenes import EVERYDAY, PRESET_PRINCIPLED, PRESETS, _principled_export
    scenes = {s.name: s for s in PEER_SCENES}
    sc = scenes["everyday"]
    assert sc.principled is EVERYDAY and sc.same_material
    data = sc.build(8)
    for name, p in EVERYDAY.items():
        # Lamina renders what the add-on exports for the same settings, within its reach.
        material, notes = _principled_export().principled_material(p)
        assert data["materials"][name] == material and notes == [], name
    job = json.loads(convert.prepare(data, tmp_path / "everyday", principled=sc.principled).read_text())
    assert job["materials"] == {}                     # nothing converted: Cycles gets Principled nodes
    assert job["principled"]["gold"] == {"Base Color": [0.9, 0.7, 0.3], "Metallic": 1.0, "Roughness": 0.3}
    assert job["principled"]["glass"]["Transmission Weight"] == 1.0
    assert job["principled"]["coated copper"]["Coat Weight"] == 1.0
    assert [(x["type"], x["strength"], x["angle"]) for x in job["lights"]] == [("sun", 3.0, 5.0)]

    sc = scenes["presets"]
    assert not sc.same_material
    data = sc.build(8)
    assert all(data["materials"][p] == p for p in PRESETS)          # Lamina renders the presets by name
    job = json.loads(convert.prepare(data, tmp_path / "presets", principled=sc.principled).read_text())
    assert set(job["principled"]) == {"ground", *PRESET_PRINCIPLED} and job["materials"] == {}
    assert job["principled"]["anodized-aluminium-blue"]["Coat Tint"] == [0.01, 0.06, 0.42]
    with pytest.raises(convert.Unsupported):          # a preset has no converted Cycles twin
        convert.prepare(data, tmp_path / "bad")


def test_converter_refuses_principled_settings_it_cannot_pass_on(tmp_path):
    base = furnace(8)
    for bad in ({"lambert": {"subsurface_weight": 1.0}},                 # not a principled_material key
                {"lambert": {"base_color": (1.0, 1.0)}},                 # not an RGB colour
                {"lambert": {"distribution": "multi_ggx"}},              # Lamina is single-scattering
                {"lambert": {"emission": (1.0, 1.0, 1.0)}},              # no emitting surfaces
                {"no such material": {"roughness": 0.5}}):              # a typo would convert the original
        with pytest.raises(convert.Unsupported):
            convert.prepare(copy.deepcopy(base), tmp_path / "bad", principled=bad)
