"""Per-interface normal maps in layered stacks (Guo et al. §3: the segment term becomes
τ·|⟨n_a, d⟩|·|⟨n_b, d⟩|/|cos d|): closed form, estimator agreement, sampling vs eval."""
import numpy as np
import pytest

from backend.layered.probe import describe, iface_eval, interface_block
from backend.materials.base import IMPORTANCE
from backend.materials.conductor import ConductorMaterial
from layered_util import bind, direction, eval_stats, load, mixture_directions

TILT = [0.35, -0.2, 0.9]


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def test_identity_normal_is_no_normal_map():
    d = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "normal": [0, 0, 1]},
                                           {"type": "diffuse"}], "media": [{"sigma_t": 0.5}]}
    b = bind(load(d), 3)
    assert not describe(b)["interfaces"][0]["framed"]


def test_tilted_conductor_under_null_matches_closed_form():
    """null / empty / conductor with a tilted normal: one path. By the segment rule,
    eval = (|⟨n, ωi⟩|/cos θi) · f_sh(ωi, ωo) |⟨n, ωo⟩| with f_sh the conductor in the shading frame."""
    d = {"type": "layered", "interfaces": [{"type": "null"},
                                           {"type": "conductor", "metal": "Au", "roughness": 0.3, "normal": TILT}],
         "media": [{"sigma_t": 0.0}]}
    mat = load(d)
    n = unit(TILT)
    wi = np.array([direction(20.0, 10.0), direction(50.0, 120.0), direction(35.0, 250.0)])
    wo = np.array([direction(40.0, 200.0), direction(25.0, 300.0), direction(60.0, 80.0)])
    # Closed form with the standalone conductor in the shading frame.
    frame = interface_block(ConductorMaterial.named("Au", roughness=0.3), normal=n)
    ref = []
    for a, b in zip(wi, wo):
        v, _, _ = iface_eval(frame, a[None], b[None])
        ref.append(v[0] * abs(a @ n) / a[2])
    ref = np.array(ref)
    rng = np.random.default_rng(2)
    for est in ("uni", "bi"):
        mu, se = eval_stats(mat, wi, wo, 3000, rng, estimator=est)
        assert np.all(np.abs(mu - ref) <= 4 * se + 1e-9 * ref), (est, mu, ref, se)
    assert np.all(ref > 0)


NM_STACK = {"type": "layered",
            "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.15, "normal": TILT},
                           {"type": "conductor", "metal": "Cu", "roughness": 0.2, "normal": [-0.2, 0.3, 0.93]}],
            "media": [{"sigma_t": 0.8, "albedo": [0.9, 0.7, 0.5], "phase": {"type": "hg", "g": 0.4}}]}


def test_normal_mapped_stack_estimators_agree():
    mat = load(NM_STACK)
    wi = np.array([direction(10.0, 0.0), direction(45.0, 60.0), direction(70.0, 200.0)])
    wo = np.array([direction(30.0, 180.0), direction(55.0, 300.0), direction(20.0, 90.0)])
    rng = np.random.default_rng(4)
    mu_u, se_u = eval_stats(mat, wi, wo, 12000, rng, estimator="uni")
    mu_b, se_b = eval_stats(mat, wi, wo, 3000, rng, estimator="bi")
    se = np.hypot(se_u, se_b)
    assert np.all(np.abs(mu_u - mu_b) <= 4 * se), ((mu_u - mu_b) / se)
    assert np.median(se / mu_b) < 0.06


@pytest.mark.parametrize("theta", [15.0, 60.0])
def test_normal_mapped_stack_sampling_matches_eval(theta):
    """Total reflectance from forward samples equals ∫ eval (both carry the same normal-map
    factors: the definition is symmetric)."""
    mat = load(NM_STACK)
    rng = np.random.default_rng(6)
    wi1 = direction(theta, 30.0)
    n = 100_000
    s = bind(mat, n).sample(np.repeat(wi1[None], n, axis=0), rng, IMPORTANCE, want_pdf=False)
    w = s.weight[:, 1]
    m = 30_000
    d, q = mixture_directions(mat, wi1, m, rng)
    x = bind(mat, m).eval(np.repeat(wi1[None], m, axis=0), d, rng, IMPORTANCE)[:, 1] / q
    se = np.hypot(w.std() / np.sqrt(n), x.std() / np.sqrt(m))
    assert abs(w.mean() - x.mean()) <= 4 * se, (w.mean(), x.mean(), se)
    assert se < 0.03 * w.mean()


def test_normal_mapped_reflection_stack_is_reciprocal():
    """The symmetric segment term keeps f(ωi, ωo) = f(ωo, ωi) (no adjoint correction needed)."""
    mat = load(NM_STACK)
    a = np.array([direction(15.0, 20.0), direction(50.0, 140.0)])
    b = np.array([direction(40.0, 230.0), direction(25.0, 10.0)])
    rng = np.random.default_rng(8)
    m1, s1 = eval_stats(mat, a, b, 6000, rng)
    m2, s2 = eval_stats(mat, b, a, 6000, rng)
    f1, f2 = m1 / b[:, 2:3], m2 / a[:, 2:3]
    se = np.hypot(s1 / b[:, 2:3], s2 / a[:, 2:3])
    assert np.all(np.abs(f1 - f2) <= 4 * se), (f1, f2, se)
