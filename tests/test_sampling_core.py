"""Warps and discrete distributions against their densities (chi-square), textures lookups."""
import numpy as np
import pytest
from scipy import stats as sst

from backend.sampling import warp
from backend.sampling.discrete import Discrete1D, PiecewiseConstant2D

ALPHA = 1e-3


def chi2_pvalue(observed, expected, min_expected=5.0):
    """Pearson chi-square with bins of small expectation pooled into one."""
    observed = np.asarray(observed, float).ravel()
    expected = np.asarray(expected, float).ravel()
    small = expected < min_expected
    obs = np.append(observed[~small], observed[small].sum())
    exp = np.append(expected[~small], expected[small].sum())
    keep = exp > 0
    assert np.all(obs[~keep] == 0), "samples landed where the density is zero"
    obs, exp = obs[keep], exp[keep]
    stat = ((obs - exp) ** 2 / exp).sum()
    return sst.chi2.sf(stat, obs.size - 1)


def bin_sphere(d, n_theta=16, n_phi=32):
    ct = np.clip(d[:, 2], -1, 1)
    phi = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi)
    i = np.minimum(((1 - ct) / 2 * n_theta).astype(int), n_theta - 1)
    j = np.minimum((phi / (2 * np.pi) * n_phi).astype(int), n_phi - 1)
    return np.bincount(i * n_phi + j, minlength=n_theta * n_phi).reshape(n_theta, n_phi)


def expected_sphere(pdf, n, n_theta=16, n_phi=32, sub=8):
    """Integrate a direction pdf over each (cosθ, φ) bin with a midpoint rule (sub×sub per bin)."""
    u = (np.arange(n_theta * sub) + 0.5) / (n_theta * sub)
    v = (np.arange(n_phi * sub) + 0.5) / (n_phi * sub)
    ct = 1 - 2 * u
    phi = 2 * np.pi * v
    CT, PHI = np.meshgrid(ct, phi, indexing="ij")
    st = np.sqrt(1 - CT ** 2)
    d = np.stack([st * np.cos(PHI), st * np.sin(PHI), CT], -1).reshape(-1, 3)
    p = pdf(d).reshape(n_theta * sub, n_phi * sub)
    cell = (2.0 / (n_theta * sub)) * (2 * np.pi / (n_phi * sub))  # dω = dcosθ dφ
    return (p * cell).reshape(n_theta, sub, n_phi, sub).sum(axis=(1, 3)) * n


@pytest.mark.parametrize("name", ["cosine", "sphere", "cone"])
def test_direction_warps_match_their_pdf(name):
    rng = np.random.default_rng(11)
    n = 200_000
    u = rng.random((n, 2))
    if name == "cosine":
        d, pdf = warp.square_to_cosine_hemisphere(u), warp.cosine_hemisphere_pdf
    elif name == "sphere":
        d, pdf = warp.square_to_uniform_sphere(u), warp.uniform_sphere_pdf
    else:
        cos_max = np.cos(np.radians(50))
        d = warp.square_to_uniform_cone(u, cos_max)

        def pdf(w):
            return np.where(w[:, 2] >= cos_max, warp.uniform_cone_pdf(cos_max), 0.0)
    assert np.allclose(np.linalg.norm(d, axis=1), 1)
    assert chi2_pvalue(bin_sphere(d), expected_sphere(pdf, n)) > ALPHA


def test_triangle_warp_is_uniform():
    rng = np.random.default_rng(3)
    b = warp.square_to_triangle_barycentric(rng.random((100_000, 2)))
    assert np.all(b >= 0) and np.all(b.sum(1) <= 1 + 1e-12)
    # Uniform on the triangle: in a 10×10 grid over the unit square, cells fully inside the
    # triangle b0 + b1 <= 1 all get the same expected count.
    i = np.minimum((b[:, 0] * 10).astype(int), 9)
    j = np.minimum((b[:, 1] * 10).astype(int), 9)
    counts = np.bincount(i * 10 + j, minlength=100).reshape(10, 10)
    inside = (np.arange(10)[:, None] + np.arange(10)[None, :]) <= 8
    exp = np.full(inside.sum(), 100_000 * 2 * 0.01)
    assert chi2_pvalue(counts[inside], exp) > ALPHA


def test_discrete_1d_matches_weights():
    rng = np.random.default_rng(5)
    w = np.array([0.0, 3.0, 1.0, 0.0, 6.0])
    dist = Discrete1D(w)
    idx, p, u_rem = dist.sample(rng.random(100_000))
    assert np.all(w[idx] > 0)
    assert np.allclose(p, w[idx] / w.sum())
    assert chi2_pvalue(np.bincount(idx, minlength=5)[w > 0], 100_000 * w[w > 0] / w.sum()) > ALPHA
    assert np.all((u_rem >= 0) & (u_rem < 1))
    assert sst.kstest(u_rem, "uniform").pvalue > ALPHA  # remapped numbers stay uniform


def test_piecewise_constant_2d_matches_table():
    rng = np.random.default_rng(8)
    table = rng.random((12, 20)) ** 3
    table[3, :] = 0.0
    dist = PiecewiseConstant2D(table)
    n = 300_000
    xy, pdf = dist.sample(rng.random((n, 2)))
    assert np.allclose(pdf, dist.pdf(xy))
    col = np.minimum((xy[:, 0] * 20).astype(int), 19)
    row = np.minimum((xy[:, 1] * 12).astype(int), 11)
    counts = np.bincount(row * 20 + col, minlength=240).reshape(12, 20)
    assert counts[3].sum() == 0
    assert chi2_pvalue(counts, n * table / table.sum()) > ALPHA
    # The density is normalised over the unit square.
    assert abs(dist.density.mean() - 1.0) < 1e-12


def _urena_reference(x0, y0, z0, lx, ly, u0, u1):
    """Ureña, Fajardo and King (2013), Algorithm 1, written out from the paper in NumPy: the
    independent reference of the per-lane spherical-rectangle sampler (which rewrites it for
    fewer square roots and divisions)."""
    z0 = -np.abs(z0)
    x1, y1 = x0 + lx, y0 + ly
    v00, v01 = np.stack([x0, y0, z0], -1), np.stack([x0, y1, z0], -1)
    v10, v11 = np.stack([x1, y0, z0], -1), np.stack([x1, y1, z0], -1)
    unit = lambda a: a / np.linalg.norm(a, axis=-1, keepdims=True)            # noqa: E731
    n0, n1 = unit(np.cross(v00, v10)), unit(np.cross(v10, v11))
    n2, n3 = unit(np.cross(v11, v01)), unit(np.cross(v01, v00))
    g = [np.arccos(np.clip(-np.sum(a * b, -1), -1, 1)) for a, b in ((n0, n1), (n1, n2), (n2, n3), (n3, n0))]
    solid = g[0] + g[1] + g[2] + g[3] - 2 * np.pi
    b0, b1 = n0[:, 2], n2[:, 2]
    au = u0 * solid - g[2] - g[3] + 2 * np.pi
    fu = (np.cos(au) * b0 - b1) / np.sin(au)
    cu = np.clip(np.sign(fu) / np.sqrt(fu * fu + b0 * b0), -1, 1)
    xu = np.clip(-(cu * z0) / np.sqrt(1 - cu * cu), x0, x1)
    d = np.sqrt(xu * xu + z0 * z0)
    h0, h1 = y0 / np.sqrt(d * d + y0 * y0), y1 / np.sqrt(d * d + y1 * y1)
    hv = h0 + u1 * (h1 - h0)
    yv = np.clip(hv * d / np.sqrt(1 - hv * hv), y0, y1)
    return solid, xu, yv


def test_spherical_rectangle_sampler_matches_the_papers_algorithm():
    """Same solid angle, same points (to 1e-7 of the rectangle's size) as the paper's algorithm
    on 20 000 random rectangles and sample pairs, and the returned distance is the point's."""
    from backend.sampling.spherical_rect import sample_spherical_rect, spherical_rect
    rng = np.random.default_rng(7)
    n = 20000
    x0, y0 = rng.uniform(-2, 1, n), rng.uniform(-2, 1, n)
    z0 = -rng.uniform(0.05, 2, n)
    lx, ly = rng.uniform(0.1, 2, n), rng.uniform(0.1, 2, n)
    u = rng.uniform(0.001, 0.999, (n, 2))
    r = spherical_rect(x0, y0, z0, lx, ly)
    solid, xu_ref, yv_ref = _urena_reference(x0, y0, z0, lx, ly, u[:, 0], u[:, 1])
    np.testing.assert_allclose(r.solid_angle, solid, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r.c0, 1 - r.b0 ** 2, rtol=1e-9, atol=1e-15)
    xu, yv = sample_spherical_rect(r, u)
    size = np.maximum(lx, ly)
    assert np.max(np.abs(xu - xu_ref) / size) < 1e-7
    assert np.max(np.abs(yv - yv_ref) / size) < 1e-7
    assert np.all((xu >= x0) & (xu <= x0 + lx) & (yv >= y0) & (yv <= y0 + ly))
