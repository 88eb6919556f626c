"""Slab media: transmittance (Beer–Lambert in depth), free-flight sampling against the analytic
depth distribution, unbiasedness of the chromatic "balance" weights, direction-dependent σt,
lanes, and the scene schema."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from backend.errors import SceneError
from backend.layered.medium import GRAZING, Medium, parse_medium
from backend.layered.phase import HenyeyGreenstein, Isotropic, MicroflakeFiber
from backend.scene.reader import LoadContext, Node

N = 200_000


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def dirs(d, n=N):
    return np.tile(unit(d), (n, 1))


def test_transmittance_beer_lambert():
    m = Medium(thickness=2.0, sigma_t=[0.1, 0.5, 1.5], albedo=0.8)
    d = unit([[0.6, 0.0, -0.8], [0.0, 0.6, 0.8], [1.0, 0, 0]])
    tau0 = np.array([0.2, 1.0, 3.0])
    t = m.transmittance(d)
    assert np.allclose(t[0], np.exp(-tau0 / 0.8)) and np.allclose(t[1], np.exp(-tau0 / 0.8))
    assert np.all(t[2] == 0)  # grazing: cannot cross
    # Depth interval: downward from 0.2 to 0.7 is reachable with d_z < 0, not with d_z > 0.
    t = m.transmittance(d[:2], 0.2, 0.7)
    assert np.allclose(t[0], np.exp(-tau0 * 0.5 / 0.8)) and np.all(t[1] == 0)
    t = m.transmittance(d[:2], 0.7, 0.2)
    assert np.all(t[0] == 0) and np.allclose(t[1], np.exp(-tau0 * 0.5 / 0.8))
    assert np.all(m.transmittance(d[:2], 0.4, 0.4) == 1)
    assert np.allclose(m.optical_depth, [tau0]) and not m.is_empty and not m.grey


def test_empty_medium():
    for m in (Medium(thickness=0.0, sigma_t=3.0), Medium(thickness=1.0, sigma_t=[0, 0, 0])):
        assert m.is_empty
        rng = np.random.default_rng(1)
        d = dirs([0.3, 0, -1], 1000)
        ff = m.free_flight(np.full(1000, 0.25), d, rng)
        assert not ff.scattered.any() and np.all(ff.depth == 1.0)
        assert np.all(ff.weight == 1.0) and np.all(ff.pdf == 1.0)
        assert np.all(m.transmittance(d) == 1.0)


@pytest.mark.parametrize("start, d", [(0.0, [0.6, 0, -0.8]), (1.0, [0.0, 0.28, 0.96]), (0.35, [0.8, 0.0, -0.6]),
                                      (0.35, [0.3, 0.1, 0.2])])
def test_grey_free_flight_distribution(start, d):
    """Scatter depths follow the exponential in depth with rate σ/|d_z| truncated at the
    boundary; the pass frequency is exp(−σ Δmax/|d_z|); weights are exactly albedo / 1."""
    sigma, albedo = 1.3, np.array([0.2, 0.5, 0.9])
    m = Medium(thickness=1.0, sigma_t=sigma, albedo=list(albedo))
    d = unit(d)
    up = d[2] > 0
    dmax = start if up else 1 - start
    rate = sigma / abs(d[2])
    rng = np.random.default_rng(2)
    ff = m.free_flight(np.full(N, start), dirs(d), rng)
    p_pass = math.exp(-rate * dmax)
    passed = ~ff.scattered
    assert abs(passed.mean() - p_pass) < 4 * math.sqrt(p_pass * (1 - p_pass) / N)
    assert np.all(ff.depth[passed] == (0.0 if up else 1.0))
    travelled = np.abs(ff.depth[ff.scattered] - start)
    cdf = lambda x: -np.expm1(-rate * x) / -math.expm1(-rate * dmax)
    assert stats.kstest(travelled, cdf).pvalue > 1e-3
    assert np.all(ff.weight[ff.scattered] == albedo) and np.all(ff.weight[passed] == 1.0)
    assert np.allclose(ff.pdf[ff.scattered], rate * np.exp(-rate * travelled), rtol=1e-12)
    assert np.allclose(ff.pdf[passed], p_pass, rtol=1e-12)
    # The stand-alone density agrees with what free_flight returned.
    again = m.free_flight_pdf(np.full(N, start), ff.depth, dirs(d), ff.scattered)
    assert np.allclose(again, ff.pdf, rtol=1e-12)


@pytest.mark.parametrize("sigma", [[0.2, 1.0, 4.0], [0.0, 0.5, 2.0], [30.0, 0.1, 0.1]])
def test_chromatic_weights_unbiased(sigma):
    """Balance strategy: E[w_k · 1{pass}] = T_k and E[w_k · 1{scatter within depth z0}] =
    albedo_k (1 − e^{−σ_k z0/|d_z|}) for every channel k (4 standard errors)."""
    albedo = np.array([0.9, 0.5, 0.7])
    sigma = np.array(sigma)
    m = Medium(thickness=1.0, sigma_t=list(sigma), albedo=list(albedo))
    d = unit([0.6, 0.0, -0.8])
    rng = np.random.default_rng(3)
    ff = m.free_flight(np.zeros(N), dirs(d), rng)
    assert np.all(np.isfinite(ff.weight)) and np.all(ff.weight >= 0)
    rate = sigma / 0.8
    checks = [(~ff.scattered, np.exp(-rate))]
    for z0 in (0.1, 0.5, 1.0):
        checks.append((ff.scattered & (ff.depth <= z0), albedo * -np.expm1(-rate * z0)))
    for mask, exact in checks:
        x = ff.weight * mask[:, None]
        mean, se = x.mean(axis=0), x.std(axis=0) / math.sqrt(N)
        assert np.all(np.abs(mean - exact) <= 4 * se + 1e-15), (mean, exact, se)


def test_chromatic_depth_histogram_matches_pdf():
    """Chi-square of sampled scatter depths against the balance density mean_k rate_k e^{−rate_k z}."""
    sigma = np.array([0.3, 1.0, 5.0])
    m = Medium(thickness=1.0, sigma_t=list(sigma), albedo=1.0)
    d = unit([0.0, 0.6, -0.8])
    rate = sigma / 0.8
    rng = np.random.default_rng(4)
    ff = m.free_flight(np.zeros(N), dirs(d), rng)
    edges = np.linspace(0.0, 1.0, 41)
    cdf = lambda z: np.mean(-np.expm1(-np.outer(z, rate)), axis=1)
    expected = np.append(np.diff(cdf(edges)), np.mean(np.exp(-rate))) * N
    observed = np.append(np.histogram(ff.depth[ff.scattered], edges)[0], (~ff.scattered).sum())
    stat = ((observed - expected) ** 2 / expected).sum()
    assert stats.chi2.sf(stat, len(expected) - 1) > 1e-3
    assert np.allclose(ff.pdf[ff.scattered], np.mean(rate * np.exp(-np.outer(ff.depth[ff.scattered], rate)), axis=1))


def test_long_steps_do_not_underflow_to_nan():
    """Very thick chromatic slab at a shallow angle: weights stay finite."""
    m = Medium(thickness=1.0, sigma_t=[1e-3, 200.0, 800.0], albedo=[1, 1, 1])
    d = unit([0.9999, 0, -0.014])
    rng = np.random.default_rng(5)
    ff = m.free_flight(np.zeros(10_000), dirs(d, 10_000), rng)
    assert np.all(np.isfinite(ff.weight)) and np.all(np.isfinite(ff.pdf))
    # Channels 1 and 2 cannot survive a step of ~1/|d_z| = 71 depth units: the weight is carried by channel 0.
    assert ff.scattered.any()


def test_grazing_lanes_are_dead():
    m = Medium(thickness=1.0, sigma_t=[1, 2, 3])
    d = unit(np.array([[1.0, 0.0, GRAZING / 10], [0.6, 0, -0.8]]))
    ff = m.free_flight(np.array([0.5, 0.5]), d, np.random.default_rng(6))
    assert np.all(ff.weight[0] == 0) and ff.pdf[0] == 0 and not ff.scattered[0] and ff.depth[0] == 0.5
    assert np.all(ff.weight[1] > 0)


def test_direction_dependent_extinction():
    """Microflake medium: σt(ω) = τ0 · 2σ_fiber(ω); free flights use it."""
    phase = MicroflakeFiber(0.05, [1, 0, 0])
    m = Medium(thickness=0.5, sigma_t=2.0, albedo=1.0, phase=phase)
    assert m.directional
    along = unit([0.8, 0.0, -0.6])   # partly along the fiber: small σ
    across = unit([0.0, 0.8, -0.6])  # across the fiber: σ ≈ (4/π) τ0
    for d in (along, across):
        tau = 1.0 * float(phase.sigma_scale(d[None])[0])
        assert np.allclose(m.transmittance(d[None]), math.exp(-tau / 0.6))
        ff = m.free_flight(np.zeros(N), dirs(d), np.random.default_rng(7))
        p = math.exp(-tau / 0.6)
        assert abs((~ff.scattered).mean() - p) < 4 * math.sqrt(p * (1 - p) / N)
    assert phase.sigma_scale(across[None])[0] > 1.2 > phase.sigma_scale(along[None])[0]
    assert np.allclose(m.sigma_s(across[None]), m.density(across[None]) * 1.0)


def test_per_lane_media_and_take():
    rng = np.random.default_rng(8)
    n = 1000
    thick = rng.uniform(0.1, 2.0, n)
    sig = rng.uniform(0.0, 3.0, (n, 3))
    alb = rng.uniform(0.0, 1.0, (n, 3))
    m = Medium(thick, sig, alb, HenyeyGreenstein(rng.uniform(-0.5, 0.5, n)))
    d = unit(rng.standard_normal((n, 3)))
    t = m.transmittance(d)
    assert np.allclose(t, np.exp(-sig * thick[:, None] / np.abs(d[:, 2:3])))
    idx = rng.permutation(n)[:100]
    sub = m.take(idx)
    assert np.allclose(sub.transmittance(d[idx]), t[idx])
    assert np.allclose(sub.phase.eval(d[idx], -d[idx]), m.phase.eval(d, -d)[idx])
    # Per-lane grey σt (1-D array) is grey, never mistaken for RGB even with 3 lanes.
    g3 = Medium(np.ones(3), np.array([1.0, 2.0, 3.0]))
    assert g3.grey and np.allclose(g3.optical_depth, [[1, 1, 1], [2, 2, 2], [3, 3, 3]])


# ---------------------------------------------------------------------------- schema
def _node(obj):
    return Node(obj, "materials.m.media[1]", LoadContext("scene.json"))


def test_parse_medium_reference_example():
    spec = parse_medium(_node({"thickness": 1.0, "sigma_t": 0.5, "albedo": [0.5, 0.7, 0.95],
                               "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, 0.5, 0]}}))
    assert spec.grey and spec.directional and not spec.is_empty and not spec.uses_textures
    m = spec.bind(np.zeros((8, 2)))
    assert np.allclose(m.optical_depth, 0.5) and np.allclose(m.albedo, [[0.5, 0.7, 0.95]])
    assert isinstance(m.phase, MicroflakeFiber)


def test_parse_medium_defaults_and_rgb():
    spec = parse_medium(_node({}))
    m = spec.bind(np.zeros((2, 2)))
    assert isinstance(m.phase, Isotropic) and np.allclose(m.optical_depth, 1) and np.allclose(m.albedo, 1)
    spec = parse_medium(_node({"sigma_t": [1, 2, 3], "thickness": 0.5, "phase": {"type": "hg", "g": 0.3}}))
    assert not spec.grey
    assert np.allclose(spec.bind(np.zeros((2, 2))).optical_depth, [[0.5, 1, 1.5]])
    assert parse_medium(_node({"sigma_t": [2, 2, 2]})).grey
    assert parse_medium(_node({"sigma_t": 0})).is_empty and parse_medium(_node({"thickness": 0})).is_empty


@pytest.mark.parametrize("obj, msg", [
    ({"thickness": -1}, "media[1].thickness: expected a number >= 0"),
    ({"sigma_t": [1, 2]}, "media[1].sigma_t: expected an RGB colour"),
    ({"albedo": [0.5, 1.2, 0.5]}, "media[1].albedo[1]"),
    ({"phase": {"type": "hg", "g": "x"}}, "media[1].phase.g"),
    ({"sigmat": 1}, "media[1].sigmat: unknown field"),
])
def test_parse_medium_errors(obj, msg):
    with pytest.raises(SceneError) as err:
        parse_medium(_node(obj))
    assert msg in str(err.value)
