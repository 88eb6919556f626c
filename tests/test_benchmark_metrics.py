"""The benchmark report's measuring code: error metrics with reference-noise removal, fits."""
import math

import numpy as np

from benchmarks.measure import Run, apply_patch, errors, fit_cost, fit_loglog, reference_noise, time_at_error


def _run(image, var):
    h, w = image.shape[:2]
    return Run("t", 4, 0, 1, 1.0, 1.0, image, var, np.full((h, w), 4))


def test_reference_noise_is_removed_from_the_mse():
    # Truth T; a noisy reference R and a noisier image I with known per-pixel variances. The
    # corrected MSE must estimate MSE(I) = σ_I² (not σ_I² + σ_R²) within 4 standard errors.
    rng = np.random.default_rng(3)
    h, w = 200, 300
    truth = rng.random((h, w, 3)) + 0.5
    s_ref, s_img = 0.05, 0.1
    ref = _run(truth + rng.normal(0, s_ref, truth.shape), np.full(truth.shape, s_ref ** 2))
    img = _run(truth + rng.normal(0, s_img, truth.shape), np.full(truth.shape, s_img ** 2))
    m = errors(img, ref)
    n = truth.size
    # (I − R) ~ N(0, σI² + σR²): the variance of the mean of its square is 2 (σI² + σR²)² / n.
    se = math.sqrt(2 * (s_img ** 2 + s_ref ** 2) ** 2 / n)
    assert abs(m["mse"] - s_img ** 2) < 4 * se
    assert abs(m["mse_raw"] - (s_img ** 2 + s_ref ** 2)) < 4 * se
    assert abs(m["consistency"] - 1) < 4 * se / s_img ** 2
    noise = reference_noise(ref)
    assert math.isclose(noise["ref_mse"], s_ref ** 2)


def test_fits_recover_exact_power_laws_and_costs():
    t = np.array([0.5, 1, 2, 4, 8, 16])
    e = 3.0 * t ** -0.5
    slope, icpt, se = fit_loglog(t, e)
    assert math.isclose(slope, -0.5, abs_tol=1e-12) and math.isclose(math.exp(icpt), 3.0, rel_tol=1e-12)
    assert se < 1e-9
    assert math.isclose(time_at_error(t, e, 3.0 / 4), 16.0, rel_tol=1e-9)
    t0, c = fit_cost([1, 2, 4, 8], [0.3 + 0.1 * s for s in (1, 2, 4, 8)])
    assert math.isclose(t0, 0.3, abs_tol=1e-12) and math.isclose(c, 0.1, rel_tol=1e-12)


def test_variants_are_deep_merged_patches():
    base = {"render": {"spp": 4, "layered": {"pdf": "approx"}}, "film": {"width": 8}}
    out = apply_patch(base, {"render": {"layered": {"estimator": "uni"}}})
    assert out["render"] == {"spp": 4, "layered": {"pdf": "approx", "estimator": "uni"}}
    assert base["render"]["layered"] == {"pdf": "approx"}   # the original is untouched
