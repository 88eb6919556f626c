"""Cross-validation of the layered estimators (issue 3 acceptance): unidirectional vs
bidirectional eval, forward-sampling histograms vs eval, reciprocity, pdfs.

Tolerances are k standard errors, the standard errors estimated from the samples themselves;
each test also checks that it has power (standard errors small against the values compared).
"""
import numpy as np
import pytest
from scipy import stats as sps

from stats_util import sidak

from backend.materials.base import IMPORTANCE, RADIANCE
from layered_util import (LOSSLESS_SAMPLER, N_AZ, PSI_EDGES, REFERENCE, REFERENCE_NESTED_UNI, STACKS, TRANSMISSIVE, bind, cells_of, direction,
                          eval_stats, load, mixture_directions, peak_frames, uniform_sphere)

K = 4.0


def grid_pairs(transmissive: bool):
    """(wi, wo) pairs: reflection from above, and for transmissive stacks transmission both ways
    and reflection from below."""
    wis = [direction(0.0), direction(35.0, 20.0), direction(70.0, 0.0)]
    wos = [direction(20.0, 180.0), direction(45.0, 10.0), direction(60.0, 90.0), direction(78.0, 200.0)]
    pairs = [(a, b) for a in wis for b in wos]
    if transmissive:
        flip = np.array([1.0, 1.0, -1.0])
        pairs += [(a, b * flip) for a in wis[:2] for b in wos[:3]]          # transmission down
        pairs += [(a * flip, b) for a in wis[1:] for b in wos[1:3]]         # transmission up
        pairs += [(a * flip, b * flip) for a in wis[:2] for b in wos[:2]]  # reflection below
    wi = np.array([p[0] for p in pairs])
    wo = np.array([p[1] for p in pairs])
    return wi, wo


def test_nested_unidirectional_agrees_with_explicit_bidirectional():
    """The paper evaluates multi-layer stacks unidirectionally through nesting (Guo et al. 2018 §4.2.1);
    the nested reference stack (uni) and the explicit one (bi) are the same BSDF."""
    nested = load(REFERENCE_NESTED_UNI)
    explicit = load(REFERENCE)
    wi, wo = grid_pairs(False)
    wi, wo = wi[::2], wo[::2]
    rng = np.random.default_rng(17)
    mu_n, se_n = eval_stats(nested, wi, wo, 4000, rng)
    mu_b, se_b = eval_stats(explicit, wi, wo, 4000, rng, estimator="bi")
    se = np.sqrt(se_n ** 2 + se_b ** 2)
    z = (mu_n - mu_b) / np.where(se > 0, se, 1.0)
    print(f"\nnested uni vs explicit bi: max |z| = {np.abs(z).max():.2f}, "
          f"median rel. SE nested {np.median(se_n / np.maximum(mu_n, 1e-12)):.3f}")
    assert np.all(np.abs(mu_n - mu_b) <= K * se), z
    assert np.median(se / np.maximum(mu_b, 1e-12)) < 0.08


@pytest.mark.parametrize("name", ["fig2-top", "transmissive"])
def test_unidirectional_and_bidirectional_agree(name):
    """Explicit uni vs bi on a grid. (On the sharp two-slab reference stack the explicit
    unidirectional estimate is heavy-tailed — single samples ~10³ × the mean, from two sharp
    lobes meeting at the exit — so no affordable sample count gives reliable standard errors;
    the reference stack is compared through nesting below, as the paper evaluates multi-layer
    stacks unidirectionally. The explicit multi-slab uni path is checked on the transmissive
    two-slab stack.)"""
    mat = load(STACKS[name])
    wi, wo = grid_pairs(mat.transmissive)
    rng = np.random.default_rng(42)
    reps = 2500
    # The unidirectional estimator is cheaper and noisier (heavier-tailed): more samples.
    mu_u, se_u = eval_stats(mat, wi, wo, 4 * reps, rng, estimator="uni")
    mu_b, se_b = eval_stats(mat, wi, wo, reps, rng, estimator="bi")
    se = np.sqrt(se_u ** 2 + se_b ** 2)
    z = (mu_u - mu_b) / np.where(se > 0, se, 1.0)
    print(f"\n{name}: {len(wi)} pairs, max |z| = {np.abs(z).max():.2f}, "
          f"median rel. SE uni {np.median(se_u / np.maximum(mu_u, 1e-12)):.3f} "
          f"bi {np.median(se_b / np.maximum(mu_b, 1e-12)):.3f}")
    assert np.all(np.abs(mu_u - mu_b) <= K * se), (z, mu_u, mu_b)
    # Power: most comparisons resolve the value to a few per cent.
    assert np.median(se / np.maximum(mu_b, 1e-12)) < 0.05


def _histogram_and_eval(mat, wi1, n_samples, rng, estimator, eval_points=30_000):
    """Weighted histogram of sample() exits per cell and the integral of eval over each cell,
    each with its standard error, on peak-centred polar cells (see _peak_frames).

    The eval integrals use one set of directions drawn from a defensive mixture: uniform over
    the exit directions (half the points) and, for each peak, one of the ψ rings chosen with
    equal probability then uniform within it. Every cell (also a sliver cut by the horizon)
    gets the unbiased estimate mean(eval · 1_cell / q)."""
    eta_out = 1.0 / mat.eta_bottom if wi1[2] < 0 else mat.eta_bottom
    frames = peak_frames(wi1, eta_out)
    nring = len(PSI_EDGES) - 1
    ncell = 2 * nring * N_AZ
    bsdf = bind(mat, n_samples)
    s = bsdf.sample(np.repeat(wi1[None], n_samples, axis=0), rng, IMPORTANCE, want_pdf=False)
    w = np.where((np.any(s.weight > 0, axis=1) & ~s.delta)[:, None], s.weight, 0.0)
    cell = cells_of(s.wo, wi1, frames)
    H = np.stack([np.bincount(cell, w[:, c], minlength=ncell) for c in range(3)], 1) / n_samples
    H2 = np.stack([np.bincount(cell, w[:, c] ** 2, minlength=ncell) for c in range(3)], 1) / n_samples
    se_H = np.sqrt(np.maximum(H2 - H * H, 0.0) / n_samples)
    m = eval_points
    d, q = mixture_directions(mat, wi1, m, rng, frames)
    ev = bind(mat, m).eval(np.repeat(wi1[None], m, 0), d, rng, IMPORTANCE, estimator=estimator)
    x = ev / q[:, None]
    c = cells_of(d, wi1, frames)
    E = np.stack([np.bincount(c, x[:, k], minlength=ncell) for k in range(3)], 1) / m
    E2 = np.stack([np.bincount(c, x[:, k] ** 2, minlength=ncell) for k in range(3)], 1) / m
    se_E = np.sqrt(np.maximum(E2 - E * E, 0.0) / m)
    return H, se_H, E, se_E


CASES = [("reference", 30.0, "bi"), ("fig2-top", 30.0, "bi"), ("fig2-top", 65.0, "bi"),
         ("transmissive", 40.0, "bi"), ("transmissive", 140.0, "bi")]


@pytest.mark.parametrize("name,theta,estimator", CASES)
def test_sample_histogram_matches_eval(name, theta, estimator):
    mat = load(STACKS[name])
    rng = np.random.default_rng(7)
    wi1 = direction(theta, 15.0)
    H, se_H, E, se_E = _histogram_and_eval(mat, wi1, 100_000, rng, estimator)
    # Cells holding less than 0.2 % of the total (slivers at the horizon, far tails) are pooled
    # per side: a few eval points cannot resolve a sliver, the pool can.
    half = H.shape[0] // 2
    small = np.max(np.maximum(H, E), axis=1) < 2e-3 * H.sum(axis=0).max()
    def pool(x, sq=False):
        out = [x[~small]]
        for sl in (slice(0, half), slice(half, None)):
            sel = small[sl]
            if sel.any():
                v = x[sl][sel]
                out.append(np.sqrt((v ** 2).sum(0, keepdims=True)) if sq else v.sum(0, keepdims=True))
        return np.concatenate(out)
    H, E, se_H, se_E = pool(H), pool(E), pool(se_H, True), pool(se_E, True)
    se = np.sqrt(se_H ** 2 + se_E ** 2)
    live = se > 0
    z = np.where(live, (H - E) / np.where(live, se, 1.0), 0.0)
    chi2 = float(np.sum(z[live] ** 2))
    p = sps.chi2.sf(chi2, int(live.sum()))
    print(f"\n{name} θ={theta} {estimator}: cells {live.sum()}, max |z| {np.abs(z).max():.2f}, "
          f"chi2 {chi2:.1f} p={p:.3f}, total sampled {H.sum(0)}, integrated eval {E.sum(0)}")
    assert np.abs(z).max() <= 4.5
    # Family-wise level 1e-3 over the histogram cases (Šidák), per-cell standard errors being
    # estimated from the samples.
    assert p > sidak(1e-3, len(CASES))
    # Totals over all cells agree too, and they are resolved to a few per cent.
    tot_se = np.sqrt((se ** 2).sum(axis=0))
    assert np.all(np.abs(H.sum(0) - E.sum(0)) <= K * tot_se)
    assert np.all(tot_se < 0.03 * H.sum(0))
    # Power per cell: the cells holding the lobe are resolved to ~10 % (a 4σ test per cell, and
    # the chi-square over ~170 cells sees coherent deviations of a few per cent).
    big = H > 0.02 * H.max()
    assert np.median(se[big] / H[big]) < 0.15


@pytest.mark.parametrize("name", ["reference", "fig2-top"])
def test_reciprocity_reflection_only(name):
    mat = load(STACKS[name])
    assert not mat.transmissive
    rng = np.random.default_rng(3)
    a = np.array([direction(10.0, 0.0), direction(40.0, 30.0), direction(65.0, 120.0), direction(25.0, 250.0)])
    b = np.array([direction(50.0, 170.0), direction(20.0, 200.0), direction(35.0, 300.0), direction(75.0, 90.0)])
    mu1, se1 = eval_stats(mat, a, b, 4000, rng)
    mu2, se2 = eval_stats(mat, b, a, 4000, rng)
    f1, s1 = mu1 / b[:, 2:3], se1 / b[:, 2:3]
    f2, s2 = mu2 / a[:, 2:3], se2 / a[:, 2:3]
    se = np.sqrt(s1 ** 2 + s2 ** 2)
    assert np.all(np.abs(f1 - f2) <= K * se), (f1, f2, se)
    assert np.median(se / f1) < 0.05


def test_transport_modes_are_adjoint_for_transmission():
    """f_radiance(wi, wo) = f_importance(wo, wi) across the whole stack (η below = 1.6):
    generalised reciprocity of the layered BSDF, which checks the η² bookkeeping."""
    mat = load(TRANSMISSIVE)
    rng = np.random.default_rng(5)
    a = np.array([direction(20.0, 0.0), direction(50.0, 40.0), direction(150.0, 10.0)])
    b = np.array([direction(160.0, 100.0), direction(130.0, 250.0), direction(30.0, 200.0)])
    mu1, se1 = eval_stats(mat, a, b, 4000, rng, mode=RADIANCE)
    mu2, se2 = eval_stats(mat, b, a, 4000, rng, mode=IMPORTANCE)
    f1, s1 = mu1 / np.abs(b[:, 2:3]), se1 / np.abs(b[:, 2:3])
    f2, s2 = mu2 / np.abs(a[:, 2:3]), se2 / np.abs(a[:, 2:3])
    se = np.sqrt(s1 ** 2 + s2 ** 2)
    assert np.all(np.abs(f1 - f2) <= K * se), (f1, f2, se)
    # The modes really differ here: (η_wi/η_wo)² = 1/1.6² for the first pair.
    assert np.all(np.abs(f1[0] - f1[0] * 1.6 ** 2) > 10 * se[0])


def _success_fraction(mat, wi1, n, rng):
    """Fraction of sampler walks (roulette off: the pdf estimator compensates roulette) that leave
    the stack with a non-zero weight through a non-delta path; microfacet samples that fail
    (single-scattering energy loss) end walks, so this is < 1 for rough dielectrics."""
    from backend.layered.probe import walks
    r = walks(bind(mat, n), np.repeat(wi1[None], n, axis=0), rng, purpose="none", rr="off")
    ok = (r.exit_weight.max(axis=1) > 0) & ~r.exit_delta
    return ok.mean(), np.sqrt(ok.mean() * (1 - ok.mean()) / n)


@pytest.mark.parametrize("name", ["lossless", "fig2-top", "transmissive"])
def test_stochastic_pdf_integrates_to_one(name):
    """∫ pdf dω over the exit directions equals the probability that the sampler returns a
    direction (1 for a loss-free sampler), within 3σ."""
    mat = load(LOSSLESS_SAMPLER if name == "lossless" else STACKS[name])
    rng = np.random.default_rng(9)
    m = 30_000
    for theta in (20.0, 65.0):
        wi1 = direction(theta, 30.0)
        d, q = mixture_directions(mat, wi1, m, rng)
        p = bind(mat, m).pdf(np.repeat(wi1[None], m, axis=0), d, rng, kind="stochastic")
        assert np.all(np.isfinite(p)) and np.all(p >= 0)
        x = p / q
        est, se = x.mean(), x.std(ddof=1) / np.sqrt(m)
        succ, se_s = (1.0, 0.0) if name == "lossless" else _success_fraction(mat, wi1, 100_000, rng)
        print(f"\n{name} θ={theta}: ∫pdf = {est:.4f} ± {se:.4f}; sampler success {succ:.4f} ± {se_s:.4f}")
        assert abs(est - succ) <= 3.0 * np.hypot(se, se_s)
        assert se < 0.06


@pytest.mark.parametrize("kind", ["approx", "lobes"])
@pytest.mark.parametrize("name", list(STACKS))
def test_mis_pdfs_positive_where_eval_positive(name, kind):
    """Every direction the BSDF has gets an MIS density (the constant guarantees it; the lobes
    pdf takes the approximate one for transmissions), finite and ≥ 0 everywhere."""
    mat = load(STACKS[name])
    rng = np.random.default_rng(2)
    m = 3000
    wi = uniform_sphere(rng, m)
    wo = uniform_sphere(rng, m)
    if not mat.transmissive:
        wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    b = bind(mat, m)
    f = b.eval(wi, wo, rng)
    p = b.pdf(wi, wo, rng, kind=kind)
    assert np.all(np.isfinite(p)) and np.all(np.isfinite(f)) and np.all(p >= 0)
    assert np.all(p[np.any(f > 0, axis=1)] > 0)
    assert (np.any(f > 0, axis=1)).mean() > 0.3


def test_nested_transmissive_middle_interface_equals_explicit():
    """A transmissive nested stack as a middle interface (entered from above and below by the
    outer walks) gives the same BSDF as the explicit stack."""
    D = lambda ior, a: {"type": "dielectric", "ior": ior, "roughness": a}  # noqa: E731
    M0 = {"sigma_t": 0.6, "albedo": 0.9, "phase": {"type": "hg", "g": 0.3}}
    M1 = {"sigma_t": 0.4, "albedo": [0.8, 0.6, 0.4], "phase": {"type": "hg", "g": -0.2}}
    M2 = {"sigma_t": 0.5, "albedo": 0.7}
    base = {"type": "conductor", "metal": "Au", "roughness": 0.25}
    explicit = load({"type": "layered", "interfaces": [D(1.5, 0.2), D(1.3, 0.25), D(1.45, 0.3), base],
                     "media": [M0, M1, M2]})
    nested = load({"type": "layered",
                   "interfaces": [D(1.5, 0.2), {"type": "layered", "interfaces": [D(1.3, 0.25), D(1.45, 0.3)],
                                                "media": [M1]}, base],
                   "media": [M0, M2]})
    assert nested.eta_slab == [1.5, 1.45] and nested.interfaces[1].transmissive
    wi = np.array([direction(20.0, 0.0), direction(55.0, 100.0)])
    wo = np.array([direction(35.0, 180.0), direction(15.0, 300.0)])
    rng = np.random.default_rng(21)
    mu_e, se_e = eval_stats(explicit, wi, wo, 3000, rng, estimator="bi")
    mu_n, se_n = eval_stats(nested, wi, wo, 3000, rng, estimator="bi")
    se = np.hypot(se_e, se_n)
    assert np.all(np.abs(mu_e - mu_n) <= K * se), ((mu_n - mu_e) / se)
    assert np.median(se / mu_e) < 0.08


@pytest.mark.parametrize("name", ["fig2-top", "transmissive"])
def test_unidirectional_without_mis_agrees_with_bidirectional(name):
    """``"mis": false`` (the benchmarks' no-MIS variant: NEE alone through a rough exit) is the
    same BSDF: it agrees with the bidirectional estimator within 4 standard errors."""
    plain = load({**STACKS[name], "estimator": "uni", "mis": False})
    ref = load(STACKS[name])
    wi, wo = grid_pairs(plain.transmissive)
    rng = np.random.default_rng(43)
    mu_u, se_u = eval_stats(plain, wi, wo, 8000, rng, estimator="uni")
    mu_b, se_b = eval_stats(ref, wi, wo, 2500, rng, estimator="bi")
    se = np.sqrt(se_u ** 2 + se_b ** 2)
    z = (mu_u - mu_b) / np.where(se > 0, se, 1.0)
    print(f"\n{name} uni without MIS: max |z| = {np.abs(z).max():.2f}")
    assert np.all(np.abs(mu_u - mu_b) <= K * se), z
    assert np.median(se / np.maximum(mu_b, 1e-12)) < 0.08


def test_mis_off_needs_the_unidirectional_estimator():
    from backend.errors import SceneError
    with pytest.raises(SceneError, match=r"mis.*estimator.*uni"):
        load({**STACKS["fig2-top"], "mis": False})
