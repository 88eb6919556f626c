"""Adaptive sampling stops converged pixels and stays unbiased; the time limit stops a render."""
import numpy as np

from render_util import front_perspective, render, scene


def half_sky_scene(spp, noise_target, min_spp):
    # A diffuse sphere fills part of the frame; background pixels see only the constant world,
    # whose estimate has zero variance, so they converge at min_spp.
    return scene(64, 64, front_perspective(4.0, 0.3),
                 {"m": {"type": "diffuse", "color": 0.8}},
                 {"ball": {"shape": "sphere", "radius": 0.8, "segments": 48}},
                 [{"mesh": "ball", "to_world": [[1, 0, 0, 0.6], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
                   "materials": ["m"]}],
                 lights=[{"type": "point", "to_world": [[1, 0, 0, -2], [0, 1, 0, -3], [0, 0, 1, 2], [0, 0, 0, 1]],
                          "power": 300.0, "color": [1, 1, 1]}],
                 world={"type": "constant", "color": [0.3, 0.3, 0.3], "strength": 1.0},
                 render={"spp": spp, "max_bounces": 3, "seed": 4, "noise_target": noise_target,
                         "min_spp": min_spp})


def test_adaptive_sampling_stops_converged_pixels_and_stays_unbiased():
    adaptive = render(half_sky_scene(512, 0.01, 16))
    counts = adaptive.film.counts()
    img = adaptive.film.combined()
    background = np.all(np.abs(img - 0.3) < 1e-9, axis=2)
    assert background.mean() > 0.3
    # Background pixels stopped after the first round, object pixels went on.
    assert counts[background].max() < 512
    assert counts[~background].max() == 512 or counts[~background].mean() > counts[background].mean()
    # Unbiased: object pixels agree with a uniform render within noise.
    uniform = render(half_sky_scene(128, 0.0, 16))
    a, b = img[~background], uniform.film.combined()[~background]
    va = adaptive.film.variance_of_mean()[~background]
    vb = uniform.film.variance_of_mean()[~background]
    diff = (a - b).mean(axis=0)
    se = np.sqrt(va.sum(axis=0) + vb.sum(axis=0)) / a.shape[0]
    assert np.all(np.abs(diff) <= 4 * se + 1e-9), (diff, se)


def test_time_limit_stops_early_with_a_valid_image():
    result = render(half_sky_scene(100000, 0.0, 16), time_limit=1.0)
    assert 0 < result.film.counts().max() < 100000
    assert np.all(np.isfinite(result.film.combined()))
    assert not result.interrupted


def test_a_time_limit_shorter_than_one_pass_still_samples_every_pixel():
    """The limit never cuts the first pass short (that left unsampled, black bands): a limit
    that has passed before any sample is done gives exactly the first pass, everywhere."""
    result = render(half_sky_scene(100000, 0.0, 16), time_limit=1e-6)
    counts = result.film.counts()
    assert counts.min() >= 1 and counts.min() == counts.max(), (counts.min(), counts.max())
    assert not result.interrupted
    assert np.all(np.isfinite(result.film.combined()))


def test_the_reported_spp_is_what_the_image_holds():
    """issue 39: a time limit that stops inside a pass left more samples in some pixels than the
    'wrote … (N spp …)' line said (it counted whole passes). The summary now reads the film's
    per-pixel counts: their range and mean when they differ."""
    from backend.cli.render_one import format_summary, summarise
    result = render(half_sky_scene(100000, 0.0, 16), time_limit=1.0)
    counts = result.film.counts()
    summary = summarise(result)
    line = format_summary(summary, "out.exr").splitlines()[0]
    assert summary["spp"] == counts.max()
    if counts.min() == counts.max():
        assert f"({counts.max()} spp," in line, line
    else:
        assert summary["spp_min"] == counts.min() and abs(summary["spp_mean"] - counts.mean()) < 0.05
        assert f"({counts.min()}–{counts.max()} spp, mean {counts.mean():.1f}," in line, line
    # A film whose pixels hold different counts (as a pass cut short leaves it), deterministic.
    result.film.count[:] = 16
    result.film.count[: result.film.count.size // 4] = 32
    summary = summarise(result)
    assert (summary["spp"], summary["spp_min"], summary["spp_mean"]) == (32, 16, 20.0)
    assert "(16–32 spp, mean 20.0," in format_summary(summary, "out.exr"), format_summary(summary, "out.exr")
    result.film.count[:] = 48
    summary = summarise(result)
    assert summary["spp"] == 48 and "spp_min" not in summary
    assert "(48 spp," in format_summary(summary, "out.exr")
