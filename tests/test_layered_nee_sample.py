"""LayeredBSDF.nee_and_sample: the light connection and the continuation sample of one path
vertex from one joint walk (what the integrator calls). Each of its three outputs must be the
same estimator as the separate query it replaces, which the other layered tests validate
against independent references (slab tables, closed forms, chi-square):

* f on the connected lanes ≈ eval (bidirectional) and exactly 0 on the others;
* the sample: weighted exit histogram ≈ the integral of eval over each cell (the same check as
  test_layered_estimators.test_sample_histogram_matches_eval, now for this sampler), in RADIANCE
  transport (what the integrator uses: transmission scaled by (η_wi/η_wo)²);
* the MIS pdfs ≈ pdf() on the same directions.

Tolerances are 4 standard errors estimated from the samples; each test checks it has power.
"""
import numpy as np
import pytest
from scipy import stats as sps

from backend.materials.base import RADIANCE
from layered_util import (N_AZ, PSI_EDGES, STACKS, bind, cells_of, direction, load,
                          mixture_directions, peak_frames, repeat_pairs)
from stats_util import sidak
from test_layered_estimators import grid_pairs

K = 4.0


def _mean_se(x, reps):
    x = x.reshape(-1, reps, *x.shape[1:])
    return x.mean(axis=1), x.std(axis=1, ddof=1) / np.sqrt(reps)


@pytest.mark.parametrize("name", sorted(STACKS))
def test_connection_matches_eval_and_pdf(name):
    mat = load(STACKS[name])
    wi, wo = grid_pairs(mat.transmissive)
    reps = 4000
    a, b = repeat_pairs(wi, wo, reps)
    n = a.shape[0]
    rng = np.random.default_rng(5)
    # Every third repetition has no light connection (as for lanes whose light sample is occluded).
    keep = np.arange(reps) % 3 != 2
    nee = np.tile(keep, len(wi))
    f, p, s = bind(mat, n).nee_and_sample(a, b, nee, rng)
    assert np.all(np.isfinite(f)) and np.all(np.isfinite(p))
    assert not f[~nee].any() and not p[~nee].any()
    assert np.all(p[nee] > 0)          # approximate pdf: a constant is added, never 0
    f_n, se_n = _mean_se(f.reshape(-1, reps, 3)[:, keep].reshape(-1, 3), int(keep.sum()))
    p_n, sp_n = _mean_se(p.reshape(-1, reps)[:, keep].reshape(-1), int(keep.sum()))
    ref = bind(mat, n)
    f_r, se_r = _mean_se(ref.eval(a, b, rng, RADIANCE), reps)
    p_r, sp_r = _mean_se(ref.pdf(a, b, rng, RADIANCE), reps)
    se = np.sqrt(se_n ** 2 + se_r ** 2)
    sp = np.sqrt(sp_n ** 2 + sp_r ** 2)
    z = (f_n - f_r) / np.where(se > 0, se, 1.0)
    zp = (p_n - p_r) / (sp + 1e-9 * p_r)
    print(f"\n{name}: {len(wi)} pairs, max |z| f {np.abs(z).max():.2f}, pdf {np.abs(zp).max():.2f}")
    assert np.all(np.abs(f_n - f_r) <= K * se)
    # (+ rounding: where the approximate pdf is deterministic both sides agree to ~1e-16.)
    assert np.all(np.abs(p_n - p_r) <= K * sp + 1e-9 * p_r)
    assert np.median(se / np.maximum(f_r, 1e-12)) < 0.08      # power
    # Without the light's pdf (delta lights): zeros, the rest unchanged in kind.
    _, p0, _ = bind(mat, n).nee_and_sample(a, b, nee, rng, nee_pdf=False)
    assert not p0.any()


HIST_CASES = [("reference", 30.0), ("fig2-top", 65.0), ("transmissive", 40.0), ("transmissive", 140.0)]


@pytest.mark.parametrize("name,theta", HIST_CASES)
def test_continuation_sample_matches_eval(name, theta, n=100_000):
    """Weighted histogram of the continuation samples vs ∫eval per cell (RADIANCE), while half
    of the lanes also connect to a light direction in the same walks."""
    mat = load(STACKS[name])
    rng = np.random.default_rng(11)
    wi1 = direction(theta, 15.0)
    frames = peak_frames(wi1, 1.0 / mat.eta_bottom if wi1[2] < 0 else mat.eta_bottom)
    ncell = 2 * (len(PSI_EDGES) - 1) * N_AZ
    light_dirs, _ = mixture_directions(mat, wi1, n, rng, frames)
    wi = np.repeat(wi1[None], n, axis=0)
    _, _, s = bind(mat, n).nee_and_sample(wi, light_dirs, rng.random(n) < 0.5, rng)
    exited = np.any(s.weight > 0, axis=1)
    assert np.all(np.isfinite(s.weight))
    # The MIS pdf is there exactly where a non-delta exit is.
    assert np.all((s.pdf > 0) == (exited & ~s.delta))
    w = np.where((exited & ~s.delta)[:, None], s.weight, 0.0)
    cell = cells_of(s.wo, wi1, frames)
    H = np.stack([np.bincount(cell, w[:, c], minlength=ncell) for c in range(3)], 1) / n
    H2 = np.stack([np.bincount(cell, w[:, c] ** 2, minlength=ncell) for c in range(3)], 1) / n
    se_H = np.sqrt(np.maximum(H2 - H * H, 0.0) / n)
    m = 30_000
    d, q = mixture_directions(mat, wi1, m, rng, frames)
    x = bind(mat, m).eval(np.repeat(wi1[None], m, 0), d, rng, RADIANCE) / q[:, None]
    c = cells_of(d, wi1, frames)
    E = np.stack([np.bincount(c, x[:, k], minlength=ncell) for k in range(3)], 1) / m
    E2 = np.stack([np.bincount(c, x[:, k] ** 2, minlength=ncell) for k in range(3)], 1) / m
    se_E = np.sqrt(np.maximum(E2 - E * E, 0.0) / m)
    # Cells below 0.2 % of the total are pooled (as in test_layered_estimators).
    small = np.max(np.maximum(H, E), axis=1) < 2e-3 * H.sum(axis=0).max()
    se = np.sqrt(se_H ** 2 + se_E ** 2)
    live = ~small & np.all(se > 0, axis=1)
    z = (H[live] - E[live]) / se[live]
    # The chi-square on the channel mean per cell: the three channels of a cell come from the
    # same samples and are strongly correlated, so their z² are not independent terms.
    Hm, Em = H.mean(1), E.mean(1)
    sem = np.sqrt(np.bincount(cell, w.mean(1) ** 2, minlength=ncell) / n / n - Hm ** 2 / n
                  + np.bincount(c, x.mean(1) ** 2, minlength=ncell) / m / m - Em ** 2 / m)
    zm = np.concatenate([(Hm - Em)[live] / sem[live],
                         [(Hm - Em)[small].sum() / np.sqrt((sem[small] ** 2).sum())]])
    chi2 = float(np.sum(zm ** 2))
    p = sps.chi2.sf(chi2, zm.size)
    print(f"\n{name} θ={theta}: cells {zm.size}, max |z| {np.abs(z).max():.2f}, chi2 {chi2:.1f} "
          f"p={p:.3f}, sampled {H.sum(0)}, ∫eval {E.sum(0)}")
    assert np.abs(z).max() <= 4.5
    assert p > sidak(1e-3, len(HIST_CASES))
    tot_se = np.sqrt((se ** 2).sum(axis=0))
    assert np.all(np.abs(H.sum(0) - E.sum(0)) <= K * tot_se)
    assert np.all(tot_se < 0.03 * H.sum(0))


def test_sample_pdf_matches_pdf_of_the_sampled_direction():
    """The continuation sample's MIS pdf is pdf(wi, wo_sampled) (an independent estimate)."""
    mat = load(STACKS["fig2-top"])
    rng = np.random.default_rng(23)
    n = 60_000
    wi = np.repeat(direction(40.0, 0.0)[None], n, axis=0)
    _, _, s = bind(mat, n).nee_and_sample(wi, wi, np.zeros(n, dtype=bool), rng)
    k = np.flatnonzero(s.pdf > 0)
    assert k.size > n // 4
    again = bind(mat, k.size).pdf(wi[k], s.wo[k], rng, RADIANCE)
    diff = s.pdf[k] - again
    se = diff.std(ddof=1) / np.sqrt(k.size)
    print(f"\nmean pdf {s.pdf[k].mean():.4f} vs {again.mean():.4f} ± {se:.4f}")
    assert abs(diff.mean()) <= K * se
    assert se < 0.02 * again.mean()


def test_analytic_and_unidirectional_fall_back_to_separate_queries():
    """One interface (analytic BSDF) and the unidirectional estimator use the base class's
    eval/pdf/sample: same random stream, same numbers."""
    for d in ({"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.3}]},
              dict(STACKS["fig2-top"], estimator="uni")):
        mat = load(d)
        n = 4000
        rng = np.random.default_rng(3)
        wi = np.repeat(direction(30.0)[None], n, 0)
        wo = np.repeat(direction(50.0, 120.0)[None], n, 0)
        nee = np.arange(n) % 2 == 0
        f, p, s = bind(mat, n).nee_and_sample(wi, wo, nee, np.random.default_rng(9))
        rng = np.random.default_rng(9)
        sub = bind(mat, n).take(np.flatnonzero(nee))
        f2 = sub.eval(wi[nee], wo[nee], rng)
        p2 = sub.pdf(wi[nee], wo[nee], rng)
        s2 = bind(mat, n).sample(wi, rng)
        assert np.array_equal(f[nee], f2) and np.array_equal(p[nee], p2)
        assert np.array_equal(s.weight, s2.weight) and np.array_equal(s.wo, s2.wo)


def test_textured_stack_keeps_each_lane_its_parameters():
    """A textured preset (wood-grain thickness texture): the joint walk reorders lanes (connected
    lanes first), so each lane must keep its own texture values. f per shading point ≈ eval
    there, at 64 random (uv, wi, wo) points."""
    from backend.cli.bsdf import resolve_material
    from backend.materials.base import ShadingContext
    mat = resolve_material("lacquered-wood")
    rng = np.random.default_rng(4)
    P, reps = 64, 600
    uv = np.repeat(rng.random((P, 2)), reps, 0)
    # Cosine-distributed directions (as NEE and the camera see them); at grazing angles the
    # estimates are too heavy-tailed for 300 samples to give honest standard errors.
    u = rng.random((2, 2 * P))
    r, phi = np.sqrt(u[0]), 2 * np.pi * u[1]
    d = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u[0])], 1)
    wi, wo = np.repeat(d[:P], reps, 0), np.repeat(d[P:], reps, 0)
    nee = np.tile(np.arange(reps) % 2 == 0, P)
    f, _, s = mat.bind(ShadingContext(uv)).nee_and_sample(wi, wo, nee, rng)
    assert np.all(np.isfinite(s.weight)) and not f[~nee].any()
    ref = mat.bind(ShadingContext(uv)).eval(wi, wo, rng, RADIANCE).reshape(P, reps, 3)
    got = f.reshape(P, reps, 3)[:, ::2]
    se = np.sqrt(got.var(1, ddof=1) / got.shape[1] + ref.var(1, ddof=1) / reps)
    diff = np.abs(got.mean(1) - ref.mean(1))
    print(f"\nlacquered-wood: max |z| {np.max(diff / np.maximum(se, 1e-300)):.2f}")
    assert np.all(diff <= K * se + 1e-12)
    # Power: with the texture values of other points (the error a lane mix-up would make) the
    # same comparison fails at many points.
    uv_other = np.roll(uv.reshape(P, reps, 2), 1, axis=0).reshape(-1, 2)
    other = mat.bind(ShadingContext(uv_other)).eval(wi, wo, rng, RADIANCE).reshape(P, reps, 3)
    moved = np.abs(other.mean(1) - ref.mean(1)) > K * np.sqrt(2.0) * se
    print(f"points whose f changes with another point's texture values: {moved.any(1).mean():.0%}")
    assert moved.any(1).mean() > 0.25
