"""The closed form of a dielectric over a Lambertian body (kernels/bsdf/coated_diffuse.py) against
independent references:

1. the random walk of the very same stack (``"estimator": "bi"``): eval at direction pairs over
   a grid of stacks (smooth and rough, GGX and Beckmann, both masking forms, an absorbing
   chromatic slab, a tinted interface, an index below 1) and directions including grazing ones,
   within k standard errors of the walk's estimate (estimated here) plus the tables' stated
   interpolation error; the directional albedo against the walk's sample weights;
2. closed forms: energy conservation of a white body under a smooth interface (the Fresnel
   identities), reciprocity, the Lambertian limit of a null-like interface;
3. the sampler against its own pdf (chi-square), sample weight = eval/pdf exactly, the delta lobe
   of a smooth interface;
4. the stacks that qualify (and those that keep the walk), textures of the body and of the
   roughness.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from backend.materials.base import IMPORTANCE, RADIANCE, ShadingContext
from layered_util import DENSITY_K, cosine_over_pdf, direction, eval_stats
from layered_util import load as _load
from stats_util import SIGNIFICANCE, Grid, chi2_test, sidak

K_SIGMA = 4.5
# The tables' own error (kernels/bsdf/coated_diffuse.py: 65 μ nodes, 64 × 64 visible normals per
# integral), relative; measured by test_table_error below against 4× finer integrals.
TABLE_REL = 2e-3


def stack(top: dict, body=(0.5, 0.6, 0.7), medium: dict | None = None, **opts) -> dict:
    return {"type": "layered", "interfaces": [{"type": "dielectric", **top}, {"type": "diffuse", "color": list(body)}],
            "media": [medium or {"thickness": 1.0, "sigma_t": 0.0}], **opts}


STACKS = {
    "ggx rough": stack({"ior": 1.5, "roughness": 0.25}),
    "ggx smooth": stack({"ior": 1.5, "roughness": 0.0}, body=(0.9, 0.3, 0.05)),
    "beckmann separable": stack({"ior": 1.33, "roughness": 0.5, "distribution": "beckmann", "masking": "separable"},
                                body=(0.8, 0.8, 0.8)),
    "absorbing slab": stack({"ior": 1.6, "roughness": 0.1}, body=(0.95, 0.95, 0.95),
                            medium={"thickness": 0.5, "sigma_t": [0.1, 0.6, 1.5], "albedo": 0.0}),
    "tinted, very rough": stack({"ior": 1.45, "roughness": 0.9, "transmission_color": [0.9, 0.7, 0.5]},
                                body=(0.7, 0.7, 0.7)),
    "index below 1": stack({"ior": 0.8, "roughness": 0.3}, body=(0.6, 0.5, 0.4)),
}
PAIRS = [(0, 0, 0), (30, 45, 180), (60, 20, 90), (75, 75, 175), (45, 85, 0), (87, 60, 180), (20, 70, 30)]


def load(doc):
    """As a scene loads it (the default estimator "auto")."""
    return _load(doc, defaults={})


def closed(doc):
    m = load(doc)
    assert m.closed_form is not None
    return m


def walk(doc):
    m = load({**doc, "estimator": "bi"})
    assert m.closed_form is None
    return m


def pairs():
    wi = np.array([direction(a, 0.0) for a, _, _ in PAIRS])
    wo = np.array([direction(b, p) for _, b, p in PAIRS])
    return wi, wo


@pytest.mark.parametrize("name", list(STACKS))
def test_eval_agrees_with_the_walk(name):
    doc = STACKS[name]
    wi, wo = pairs()
    rng = np.random.default_rng(7)
    mean, se = eval_stats(walk(doc), wi, wo, 20_000, rng, mode=IMPORTANCE)
    f = closed(doc).bind(ShadingContext(np.zeros((1, 2)))).eval(wi, wo, rng, IMPORTANCE)
    z = np.abs(f - mean) / (K_SIGMA * se + TABLE_REL * np.abs(f) + 1e-9)
    assert np.all(z < 1.0), f"{name}: closed {f}\nwalk {mean} ± {se}"


@pytest.mark.parametrize("name", ["ggx rough", "absorbing slab", "ggx smooth"])
def test_albedo_agrees_with_the_walk(name):
    """Directional albedo (the integral of eval over the hemisphere, delta lobe included) at
    several angles: the closed form's against the mean of the walk's sample weights."""
    doc = STACKS[name]
    rng = np.random.default_rng(11)
    b_closed = closed(doc).bind(ShadingContext(np.zeros((1, 2))))
    b_walk = walk(doc).bind(ShadingContext(np.zeros((1, 2))))
    n = 60_000
    for theta in (0.0, 50.0, 80.0, 88.0):
        wi = np.tile(direction(theta, 0.0), (n, 1))
        s = b_walk.sample(wi, rng, IMPORTANCE, want_pdf=False)
        w = np.where(s.wo[:, 2:] > 0, s.weight, 0.0)
        mean, se = w.mean(axis=0), w.std(axis=0, ddof=1) / math.sqrt(n)
        a = b_closed.albedo(wi[:1])[0]
        assert np.all(np.abs(a - mean) < K_SIGMA * se + TABLE_REL * a), (theta, a, mean, se)


def test_white_body_under_a_smooth_interface_conserves_energy():
    """τ = 0, ρ = 1, smooth: F(μ) + (1 − F(μ))·Ē/(η²(1 − r)) = 1 by the Fresnel identities
    (1 − r = Ē/η²): the albedo is 1 at every angle, up to the tables' error."""
    b = closed(stack({"ior": 1.5, "roughness": 0.0}, body=(1, 1, 1))).bind(ShadingContext(np.zeros((1, 2))))
    for theta in (0.0, 30.0, 60.0, 80.0, 89.0):
        a = b.albedo(direction(theta)[None, :])[0]
        np.testing.assert_allclose(a, 1.0, atol=2e-3, err_msg=f"θ {theta}")


def test_reciprocity():
    rng = np.random.default_rng(3)
    for name in ("ggx rough", "absorbing slab", "beckmann separable"):
        b = closed(STACKS[name]).bind(ShadingContext(np.zeros((1, 2))))
        a = rng.normal(size=(200, 3))
        c = rng.normal(size=(200, 3))
        a[:, 2] = np.abs(a[:, 2])
        c[:, 2] = np.abs(c[:, 2])
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        c /= np.linalg.norm(c, axis=1, keepdims=True)
        f_ac = b.eval(a, c, rng) / c[:, 2:]
        f_ca = b.eval(c, a, rng) / a[:, 2:]
        np.testing.assert_allclose(f_ac, f_ca, rtol=1e-9, atol=1e-14, err_msg=name)


def test_below_the_surface_is_black():
    b = closed(STACKS["ggx rough"]).bind(ShadingContext(np.zeros((1, 2))))
    up, down = direction(30.0)[None, :], direction(150.0)[None, :]
    assert np.all(b.eval(up, down) == 0) and np.all(b.eval(down, up) == 0)


LEVEL = sidak(SIGNIFICANCE, 12)
SPHERE = Grid(20, 32, -1.0, 1.0)


@pytest.mark.parametrize("name,theta", [("ggx rough", 0.0), ("ggx rough", 70.0), ("beckmann separable", 40.0),
                                        ("index below 1", 60.0), ("ggx smooth", 45.0)])
def test_sampling_follows_the_pdf(name, theta):
    b = closed(STACKS[name]).bind(ShadingContext(np.zeros((1, 2))))
    rng = np.random.default_rng(5)
    n = 100_000
    wi_dir = direction(theta, 0.4)
    wi = np.tile(wi_dir, (n, 1))
    s = b.sample(wi, rng, RADIANCE)
    for x in s:
        assert np.all(np.isfinite(x))
    delta = s.delta
    if name == "ggx smooth":
        # The mirror: weight F(μ)/w_s with probability w_s, so its expected weight is F(μ).
        from backend.materials.fresnel import dielectric as fresnel
        F = float(fresnel(np.array([math.cos(math.radians(theta))]), 1.5)[0][0])
        np.testing.assert_allclose(s.wo[delta], np.tile(wi_dir * [-1, -1, 1], (delta.sum(), 1)), atol=1e-12)
        share = delta.mean()
        assert abs(share * s.weight[delta, 0].mean() - F) < 1e-12 + 4 * F * math.sqrt(share * (1 - share) / n) / share
    else:
        assert not delta.any()
    ok = (s.pdf > 0) & ~delta
    assert np.all(s.weight[~ok & ~delta] == 0)
    wo = s.wo[ok]
    ev = b.eval(wi[ok], wo)
    pd = b.pdf(wi[ok], wo)
    np.testing.assert_allclose(s.pdf[ok], pd, rtol=1e-9)
    np.testing.assert_allclose(s.weight[ok], ev / pd[:, None], rtol=1e-9, atol=1e-14)
    # The delta samples fall in the chi-square test's "no direction" cell, whose expected share
    # is 1 − ∫pdf (the mirror's sampling probability).
    res = chi2_test(wo, n, lambda w: b.pdf(np.broadcast_to(wi_dir, w.shape), w), SPHERE)
    assert res.p_value > LEVEL, str(res)
    # Nothing is lost: every non-delta sample produced a direction (the reflections that would
    # point below the surface are mirrored up, ``top_density``).
    assert ok.sum() + delta.sum() == n


@pytest.mark.parametrize("name", ["ggx rough", "beckmann separable", "index below 1", "tinted, very rough"])
def test_the_sampler_density_is_exact_at_grazing_incidence(name):
    """E[cos θo / pdf] = π over the sampler's own directions, down to 89° from the normal, where
    most of a rough top's reflections point below the surface: they are mirrored up and the pdf
    counts both ways in (``top_density``). Until 2026-12-07 they drew from the body instead, at
    a share tabulated over μ, and the pdf was off where that share changes fast (a
    tabulated stack of the everyday scene: E[1/pdf] = 0.83 · 2π at μ = 0.03; the
    renders' means moved 0.1 % with the light-sample count, which a consistent MIS does not)."""
    b = closed(STACKS[name]).bind(ShadingContext(np.zeros((1, 2))))
    rng = np.random.default_rng(21)
    for theta in (0.0, 60.0, 85.0, 88.0, 89.0):
        mean, se = cosine_over_pdf(b, direction(theta, 0.3), 200_000, rng, RADIANCE)
        assert abs(mean - math.pi) < DENSITY_K * se, (name, theta, mean, se)


def test_which_stacks_take_the_closed_form():
    yes = [STACKS["ggx rough"], STACKS["ggx smooth"], STACKS["absorbing slab"]]
    for doc in yes:
        assert load(doc).closed_form is not None
    no = [
        {**STACKS["ggx rough"], "estimator": "uni"},
        stack({"ior": 1.5, "roughness": 0.2, "roughness_v": 0.4}),
        stack({"ior": 1.5, "roughness": 0.2}, medium={"sigma_t": 1.0, "albedo": 0.5}),
        {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.1, "normal": [0.1, 0, 1]},
                                           {"type": "diffuse", "color": 0.5}], "media": [{"sigma_t": 0.0}]},
        {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5},
                                           {"type": "conductor", "metal": "Au"}], "media": [{"sigma_t": 0.0}]},
    ]
    for doc in no:
        assert load(doc).closed_form is None, doc


def test_textured_body_and_roughness(tmp_path):
    """A body-colour texture and a roughness texture: each lane equals the constant material at
    its texel values (the roughness through the α grid: within its interpolation error)."""
    from test_textures import write_image
    col = np.zeros((2, 2, 3), np.float32)
    col[..., 0], col[..., 1], col[..., 2] = [[0.1, 0.9], [0.5, 0.3]], 0.4, [[0.8, 0.2], [0.6, 0.7]]
    rough = np.array([[0.0, 0.3], [0.6, 1.0]], np.float32)
    write_image(tmp_path / "c.exr", col)
    write_image(tmp_path / "r.exr", np.repeat(rough[..., None], 3, axis=2))
    doc = stack({"ior": 1.5, "roughness": {"texture": str(tmp_path / "r.exr"), "channel": 0}})
    doc["interfaces"][1]["color"] = {"texture": str(tmp_path / "c.exr")}
    m = closed(doc)
    uv = np.array([[0.25, 0.75], [0.75, 0.75], [0.25, 0.25], [0.75, 0.25]])   # texel centres
    texel = [(0, 0), (0, 1), (1, 0), (1, 1)]
    wi = np.tile(direction(35.0), (4, 1))
    wo = np.tile(direction(50.0, 2.0), (4, 1))
    f = m.bind(ShadingContext(uv)).eval(wi, wo)
    for k, (r, c) in enumerate(texel):
        alpha = float(rough[r, c])
        ref = closed(stack({"ior": 1.5, "roughness": alpha}, body=tuple(float(x) for x in col[r, c])))
        g = ref.bind(ShadingContext(np.zeros((1, 2)))).eval(wi[:1], wo[:1])[0]
        np.testing.assert_allclose(f[k], g, rtol=0.02, atol=1e-4, err_msg=f"texel {texel[k]} α {alpha}")
