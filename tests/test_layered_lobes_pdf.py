"""The closed-form MIS density of layered reflections (pdf ``"lobes"``, kernels/layered/lobes.py).

Where every interface above the reflecting one is smooth and the slabs are empty, the lobe of
an inner interface is the exact density of the sampler's paths that reflect once inside: the
walk's Fresnel choices on the way in and out, the inner interface's sampling density between the
refracted directions, and the refraction's solid-angle Jacobian; likewise a transmission through
a stack with one rough interface. The independent reference is the sampler itself: a histogram
of the exit directions of walks with exactly that path (their vertex count says which), against
the density integrated over each cell. With rough interfaces
above, the lobe is an approximation (only the MIS weights use it): there the tests check that
renders stay unbiased (tests/test_layered_deferred_pdf.py) and that the density is positive
wherever the BSDF is (tests/test_layered_estimators.py)."""
import numpy as np
import pytest

from backend.layered.probe import walks
from layered_util import bind, direction, load

K = 4.5      # per cell; the Šidák-style allowance for ~200 cells at a 5e-4 family-wise rate

SMOOTH_OVER_ROUGH = {   # exit through a smooth coat after one reflection off a rough GGX metal
    "type": "layered", "pdf": "lobes", "pdf_constant": 0.0,
    "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.0},
                   {"type": "conductor", "metal": "Au", "roughness": 0.3, "roughness_v": 0.15}],
    "media": [{"sigma_t": 0.0}]}
TWO_SMOOTH_OVER_ROUGH = {   # two smooth dielectrics (into 1.5, then 1.2 below it) over rough copper
    "type": "layered", "pdf": "lobes", "pdf_constant": 0.0,
    "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.0},
                   {"type": "dielectric", "ior": 1.2, "roughness": 0.0},
                   {"type": "conductor", "metal": "Cu", "roughness": 0.25}],
    "media": [{"sigma_t": 0.0}, {"sigma_t": 0.0}]}


def _cells(n_cos=12, n_phi=16):
    ce = np.linspace(0.0, 1.0, n_cos + 1)
    pe = np.linspace(-np.pi, np.pi, n_phi + 1)
    return ce, pe


def _lobe_integrals(mat, wi1, ce, pe, rng, sub=24, side=1.0):
    """∫ p dω over each (|cos θ|, φ) cell on the side ``side`` (+1 up, −1 down) by stratified
    Monte Carlo (one jittered point in each of sub × sub sub-cells, uniform in cos θ and φ, so
    dω = d cos θ dφ), with its standard error (from the spread of pairs of neighbouring
    sub-cells, conservative for a stratified estimate)."""
    n_cos, n_phi = len(ce) - 1, len(pe) - 1
    dc, dp = (ce[1] - ce[0]) / sub, (pe[1] - pe[0]) / sub
    i, j, k, l = np.meshgrid(np.arange(n_cos), np.arange(n_phi), np.arange(sub), np.arange(sub), indexing="ij")
    c = ce[i.ravel()] + (k.ravel() + rng.random(i.size)) * dc
    ph = pe[j.ravel()] + (l.ravel() + rng.random(i.size)) * dp
    s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
    d = np.stack([s * np.cos(ph), s * np.sin(ph), side * c], axis=1)
    m = d.shape[0]
    p = bind(mat, m).pdf(np.repeat(wi1[None], m, axis=0), d, rng, kind="lobes")
    area = (ce[1] - ce[0]) * (pe[1] - pe[0])
    p = p.reshape(n_cos * n_phi, sub * sub) * area
    pairs = p.reshape(n_cos * n_phi, sub * sub // 2, 2)
    var = ((pairs[:, :, 0] - pairs[:, :, 1]) ** 2).sum(axis=1) / 2.0 / (sub * sub) ** 2
    return p.mean(axis=1), np.sqrt(var)


TRANSMISSIVE_ONE_ROUGH = {   # a smooth coat (into 1.5), a rough exit into 1.2 below, an absorbing slab
    "type": "layered", "pdf": "lobes", "pdf_constant": 0.0,
    "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.0},
                   {"type": "dielectric", "ior": 1.2, "roughness": 0.2, "roughness_v": 0.35}],
    "media": [{"sigma_t": 0.0}]}
ROUGH_COAT_OVER_GLASS = {   # a rough coat (into 1.4) over a smooth exit into air, through a null
    "type": "layered", "pdf": "lobes", "pdf_constant": 0.0,
    "interfaces": [{"type": "dielectric", "ior": 1.4, "roughness": 0.3},
                   {"type": "null"},
                   {"type": "dielectric", "ior": 1.0, "roughness": 0.0}],
    "media": [{"sigma_t": 0.0}, {"sigma_t": 0.0}]}


@pytest.mark.parametrize("spec,vertices,wi_side,exit_side", [
    (SMOOTH_OVER_ROUGH, 3, 1.0, 1.0), (TWO_SMOOTH_OVER_ROUGH, 5, 1.0, 1.0),
    (TRANSMISSIVE_ONE_ROUGH, 2, 1.0, -1.0), (TRANSMISSIVE_ONE_ROUGH, 2, -1.0, 1.0),
    (ROUGH_COAT_OVER_GLASS, 3, 1.0, -1.0)],
    ids=["one-slab", "two-slabs", "transmission-down", "transmission-up", "transmission-null"])
@pytest.mark.parametrize("theta", [15.0, 60.0])
def test_closed_form_is_the_samplers_density_with_one_rough_interface(spec, vertices, wi_side, exit_side, theta):
    mat = load(spec)
    rng = np.random.default_rng(23)
    wi1 = direction(theta, 40.0) * np.array([1.0, 1.0, wi_side])
    n = 400_000
    r = walks(bind(mat, n), np.repeat(wi1[None], n, axis=0), rng, purpose="none", rr="off")
    # The paths of the closed form: through the smooth interfaces, one rough event (a reflection
    # inside, or the transmission), out.
    hit = (r.count == vertices) & ~r.exit_delta & (r.exit_weight.max(axis=1) > 0) & (r.exit_dir[:, 2] * exit_side > 0)
    d = r.exit_dir[hit]
    ce, pe = _cells()
    counts, _, _ = np.histogram2d(np.abs(d[:, 2]), np.arctan2(d[:, 1], d[:, 0]), bins=[ce, pe])
    counts = counts.ravel()
    expected, se_int = _lobe_integrals(mat, wi1, ce, pe, rng, side=exit_side)
    expected *= n
    se_int *= n
    z = (counts - expected) / np.sqrt(np.maximum(expected, 1.0) + se_int ** 2)
    print(f"\n{theta}°: {hit.mean():.4f} of the walks; lobe mass {expected.sum() / n:.4f}; max |z| {np.abs(z).max():.2f}")
    assert hit.sum() > 20_000                         # the test has power: many paths compared
    assert abs(counts.sum() - expected.sum()) <= K * np.sqrt(expected.sum() + (se_int ** 2).sum())
    assert np.abs(z).max() < K


def _random_stack(rng):
    """A random valid stack: 2–5 interfaces (dielectrics smooth or rough and anisotropic, null;
    an opaque base or none), slabs from empty to optically thick, HG or microflake media."""
    n = int(rng.integers(2, 6))
    interfaces = []
    for i in range(n):
        last = i == n - 1
        kind = rng.choice(["conductor", "diffuse", "dielectric"]) if last else rng.choice(["dielectric", "dielectric", "null"])
        if kind == "dielectric":
            rough = float(rng.choice([0.0, rng.uniform(0.001, 1.0)]))
            interfaces.append({"type": "dielectric", "ior": float(rng.uniform(1.0001, 3.0)), "roughness": rough,
                               "roughness_v": float(rng.uniform(0.001, 1.0)) if rough > 0 else rough})
        elif kind == "conductor":
            interfaces.append({"type": "conductor", "metal": "Cu", "roughness": float(rng.choice([0.0, rng.uniform(0.001, 1.0)]))})
        else:
            interfaces.append({"type": kind} if kind == "null" else {"type": "diffuse", "color": 0.8})
    media = []
    for _ in range(n - 1):
        sig = float(rng.choice([0.0, 10.0 ** rng.uniform(-3, 2)]))
        phase = ({"type": "hg", "g": float(rng.uniform(-0.9, 0.9))} if rng.random() < 0.5 else
                 {"type": "microflake", "stddev": float(rng.uniform(0.01, 1.0)), "orientation": [1.0, 0.5, 0.2]})
        media.append({"sigma_t": sig, "albedo": float(rng.uniform(0, 1)), "phase": phase})
    return {"type": "layered", "pdf": "lobes", "interfaces": interfaces, "media": media}


def test_lobes_pdf_finite_and_non_negative_on_random_stacks():
    """Random stacks (index ratios up to 3, roughness up to 1, optical depths up to 100) and
    directions down to grazing (|cos| 1e-6), both sides: the density is finite and ≥ 0."""
    rng = np.random.default_rng(31)
    m = 2000
    for _ in range(30):
        spec = _random_stack(rng)
        mat = load(spec)
        wi = rng.normal(size=(m, 3))
        wo = rng.normal(size=(m, 3))
        wi[:m // 4, 2] = 1e-6 * np.sign(wi[:m // 4, 2])
        wo[m // 4:m // 2, 2] = 1e-6 * np.sign(wo[m // 4:m // 2, 2])
        wi /= np.linalg.norm(wi, axis=1, keepdims=True)
        wo /= np.linalg.norm(wo, axis=1, keepdims=True)
        p = bind(mat, m).pdf(wi, wo, rng, kind="lobes")
        assert np.all(np.isfinite(p)) and np.all(p >= 0), spec
        # The constant is the floor wherever the query is valid for the stack.
        valid = (wi[:, 2] * wo[:, 2] != 0) if mat.transmissive else (wi[:, 2] > 0) & (wo[:, 2] > 0)
        assert np.all(p[valid] >= 0.1 - 1e-12), spec
