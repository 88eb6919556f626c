"""Pixel-filter importance sampling: sampled offsets follow the filter profile (chi-square).

The expected bin masses come from integrating the closed-form filter (Blackman–Harris as in
Cycles, Cycles' Gaussian) by Gauss–Legendre quadrature per bin, independent of the sampler's tables.
"""
import numpy as np
import pytest
from scipy import stats

from backend.film import PixelFilter

ALPHA = 1e-3


SUPPORT = {"blackman-harris": 2.0, "gaussian": 3.0}     # Cycles: scene/film.cpp, filter_table


def _profile(kind, width, x):
    """Cycles' filter value at offset x (pixels), unnormalised: Blackman–Harris over ±width,
    Gaussian exp(−2 (6x/(3 width))²) over ±1.5 width."""
    if kind == "gaussian":
        v = x * 6.0 / (3.0 * width)
        return np.exp(-2.0 * v * v)
    v = x / (2.0 * width) + 0.5  # position across the support in [0, 1]
    a = 2.0 * np.pi * v
    return 0.35875 - 0.48829 * np.cos(a) + 0.14128 * np.cos(2 * a) - 0.01168 * np.cos(3 * a)


@pytest.mark.parametrize("kind,width", [("blackman-harris", 1.5), ("gaussian", 1.5), ("blackman-harris", 3.0)])
def test_filter_offsets_follow_the_profile(kind, width):
    n, bins = 400_000, 40
    x = PixelFilter(kind, width).sample(np.random.default_rng(5).random((n, 2)))
    half = SUPPORT[kind] * width / 2
    assert np.all(np.abs(x) <= half) and np.abs(x).max() > 0.7 * half   # the whole support is used
    edges = np.linspace(-half, half, bins + 1)
    g, w = np.polynomial.legendre.leggauss(16)
    mid, hw = 0.5 * (edges[1:] + edges[:-1]), 0.5 * np.diff(edges)
    mass = (_profile(kind, width, mid[:, None] + hw[:, None] * g) * w).sum(axis=1) * hw
    expected = n * mass / mass.sum()
    for axis in range(2):
        observed = np.histogram(x[:, axis], edges)[0]
        keep = expected >= 5
        stat = ((observed[keep] - expected[keep]) ** 2 / expected[keep]).sum()
        assert stats.chi2.sf(stat, keep.sum() - 1) > ALPHA
