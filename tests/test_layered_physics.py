"""The layered BSDF against independent references: adding-doubling slab table, white furnace
(energy conservation with closed-form delta parts), single-interface stacks, robustness."""
import csv

import numpy as np
import pytest

from backend import stats as global_stats
from backend.layered.bsdf import Options
from backend.layered.material import LayeredMaterial
from backend.layered.medium import MediumSpec
from backend.layered.phase import HenyeyGreenstein, PhaseSpec
from backend.textures import ConstantParam, ImageParam
from backend.materials.base import IMPORTANCE, RADIANCE, ShadingContext
from backend.materials.dielectric import DielectricMaterial
from backend.materials.fresnel import dielectric as fresnel
from conftest import DATA
from layered_util import (FIG2_TOP, REFERENCE, REFERENCE_NESTED_UNI, STACKS, TRANSMISSIVE, bind,
                          direction, load, mixture_directions, uniform_sphere)


def slab_rows():
    with open(DATA / "slab" / "slab_normal_incidence.csv") as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


@pytest.mark.parametrize("ior", [1.0, 1.5])
def test_slab_table_adding_doubling(ior):
    """Smooth dielectric / HG slab / smooth dielectric at normal incidence: R_total and T_total
    (delta lobes included) match Prahl's adding-doubling values within 4σ + 1e-3, every row.
    All rows of one index run as one batch with per-lane (texture-like) medium parameters."""
    rows = [r for r in slab_rows() if r["slab_ior"] == ior]
    per = 40_000
    R = len(rows)
    n = per * R
    # Per-lane medium parameters from textures: one texel per row, each lane at its texel's centre.
    def image(key, channels):
        t = np.asarray([r[key] for r in rows], np.float32).reshape(1, R, 1)
        return ImageParam(np.repeat(t, channels, axis=2), channels,
                          np.ones(3) if channels == 3 else np.asarray(1.0), key)
    medium = MediumSpec(ConstantParam(1.0, 1), image("optical_thickness", 1), image("albedo", 3),
                        PhaseSpec("hg", HenyeyGreenstein, {"g": image("hg_g", 1)}, False), grey=True)
    mat = LayeredMaterial([DielectricMaterial(ior=ior), DielectricMaterial(ior=1.0, ior_above=ior)],
                          [medium], [ior], 1.0, Options())
    uv = np.stack([np.repeat((np.arange(R) + 0.5) / R, per), np.full(n, 0.5)], axis=1)
    bsdf = mat.bind(ShadingContext(uv))
    wi = np.zeros((n, 3))
    wi[:, 2] = 1.0
    s = bsdf.sample(wi, np.random.default_rng(11), IMPORTANCE, want_pdf=False)
    w = s.weight[:, 0].reshape(len(rows), per)
    up = (s.wo[:, 2] > 0).reshape(len(rows), per)
    worst = 0.0
    for k, r in enumerate(rows):
        for value, ref in ((w[k] * up[k], r["R_total"]), (w[k] * ~up[k], r["T_total"])):
            mean, se = value.mean(), value.std(ddof=1) / np.sqrt(per)
            assert abs(mean - ref) <= 4.0 * se + 1e-3, (r, mean, se, ref)
            worst = max(worst, abs(mean - ref) / (se + 1e-12) if se > 0 else 0.0)
    print(f"\nslab n={ior}: {len(rows)} rows, worst |error|/σ = {worst:.2f}")
    assert bsdf.stats["cap_hits"] == 0


def _smooth_slab_delta(theta, n_ior, tau):
    """Closed-form unscattered reflection/transmission of smooth(n) / τ / smooth(back to 1):
    R = F + (1−F)² F T² / (1 − F²T²), T = (1−F)² T / (1 − F²T²), F the Fresnel reflectance,
    T = exp(−τ / cos θt) one crossing."""
    c = np.cos(np.radians(theta))
    F, cos_t, _ = fresnel(np.array([c]), n_ior)
    F, ct = float(F[0]), abs(float(cos_t[0]))
    T = np.exp(-tau / ct)
    den = 1.0 - F * F * T * T
    return F + (1 - F) ** 2 * F * T * T / den, (1 - F) ** 2 * T / den


LOSSLESS = {"type": "layered",
            "interfaces": [{"type": "dielectric", "ior": 1.5}, {"type": "dielectric", "ior": 1.0}],
            "media": [{"sigma_t": 1.0, "albedo": 1.0, "phase": {"type": "hg", "g": 0.3}}]}


@pytest.mark.parametrize("theta", [0.0, 40.0, 75.0])
def test_white_furnace_lossless_slab(theta):
    """Smooth / albedo-1 medium / smooth conserves energy: every sample weight is 1 (R + T = 1),
    the delta fractions match the closed form, and ∫eval + delta parts = 1 (both estimators)."""
    mat = load(LOSSLESS)
    rng = np.random.default_rng(4)
    n = 100_000
    wi1 = direction(theta, 10.0)
    s = bind(mat, n).sample(np.repeat(wi1[None], n, axis=0), rng, IMPORTANCE, want_pdf=False)
    total = s.weight.mean(axis=0)
    assert np.allclose(total, 1.0, atol=1e-12), total
    R_d, T_d = _smooth_slab_delta(theta, 1.5, 1.0)
    up = s.wo[:, 2] > 0
    for frac, ref in (((s.delta & up).mean(), R_d), ((s.delta & ~up).mean(), T_d)):
        assert abs(frac - ref) <= 4.0 * np.sqrt(ref * (1 - ref) / n) + 1e-12, (frac, ref)
    m = 30_000
    d, q = mixture_directions(mat, wi1, m, rng)
    for est in ("uni", "bi"):
        f = bind(mat, m).eval(np.repeat(wi1[None], m, axis=0), d, rng, IMPORTANCE, estimator=est)
        x = f[:, 1] / q
        integral, se = x.mean(), x.std(ddof=1) / np.sqrt(m)
        energy = integral + R_d + T_d
        print(f"\nθ={theta} {est}: ∫eval = {integral:.4f} ± {se:.4f}, + delta {R_d + T_d:.4f} = {energy:.4f}")
        assert abs(energy - 1.0) <= 3.0 * se
        assert se < 0.01


def test_white_furnace_smooth_dielectric_over_white_diffuse():
    # The walk (its closed form is tested in tests/test_coated_diffuse.py).
    mat = load({"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5},
                                                  {"type": "diffuse", "color": 1.0}],
                "media": [{"sigma_t": 0.0}], "estimator": "bi"})
    rng = np.random.default_rng(8)
    n = 50_000
    for theta in (0.0, 45.0, 80.0):
        wi1 = direction(theta)
        s = bind(mat, n).sample(np.repeat(wi1[None], n, axis=0), rng, IMPORTANCE, want_pdf=False)
        # Every walk leaves with weight 1: reflectance 1 exactly (variance 0).
        assert np.allclose(s.weight, 1.0, atol=1e-12)
        m = 20_000
        d = uniform_sphere(rng, m)
        d[:, 2] = np.abs(d[:, 2])
        f = bind(mat, m).eval(np.repeat(wi1[None], m, axis=0), d, rng, IMPORTANCE)
        x = f[:, 0] * 2 * np.pi
        F = float(fresnel(np.array([np.cos(np.radians(theta))]), 1.5)[0][0])
        assert abs(x.mean() + F - 1.0) <= 3.0 * x.std(ddof=1) / np.sqrt(m)


def test_rough_interfaces_lose_energy_and_report_it():
    """Single-scattering microfacet interfaces lose energy (no multiple scattering between
    microfacets). Measure the loss of rough(α 0.3) / albedo-1 medium / rough(α 0.3); sampling and
    eval agree on it."""
    d = {"type": "layered",
         "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.3},
                        {"type": "dielectric", "ior": 1.0, "roughness": 0.3}],
         "media": [{"sigma_t": 1.0, "albedo": 1.0, "phase": {"type": "hg", "g": 0.3}}]}
    mat = load(d)
    rng = np.random.default_rng(6)
    n = 100_000
    for theta in (0.0, 60.0):
        wi1 = direction(theta)
        s = bind(mat, n).sample(np.repeat(wi1[None], n, axis=0), rng, IMPORTANCE, want_pdf=False)
        w = s.weight[:, 0]
        total, se = w.mean(), w.std(ddof=1) / np.sqrt(n)
        m = 30_000
        dirs, q = mixture_directions(mat, wi1, m, rng)
        x = bind(mat, m).eval(np.repeat(wi1[None], m, axis=0), dirs, rng, IMPORTANCE)[:, 0] / q
        print(f"\nrough α 0.3 / albedo 1 / rough α 0.3, θ={theta}: R+T = {total:.4f} ± {se:.4f} "
              f"(energy loss {100 * (1 - total):.1f} %), ∫eval = {x.mean():.4f} ± {x.std() / np.sqrt(m):.4f}")
        assert total < 1.0 - 10 * se           # a real loss, never a gain
        assert abs(x.mean() - total) <= 4.0 * np.hypot(se, x.std(ddof=1) / np.sqrt(m))


@pytest.mark.parametrize("iface", [
    {"type": "dielectric", "ior": 1.4, "roughness": 0.2},
    {"type": "conductor", "metal": "Au", "roughness": 0.15, "distribution": "beckmann"},
    {"type": "diffuse", "color": [0.3, 0.6, 0.9]},
])
def test_single_interface_stack_is_the_analytic_bsdf(iface):
    alone = load(iface)
    stack = load({"type": "layered", "interfaces": [iface]})
    n = 500
    rng = np.random.default_rng(1)
    wi, wo = uniform_sphere(rng, n), uniform_sphere(rng, n)
    a, b = bind(alone, n), bind(stack, n)
    assert type(a) is type(b)
    for mode in (RADIANCE, IMPORTANCE):
        assert np.array_equal(a.eval(wi, wo, rng, mode), b.eval(wi, wo, rng, mode))
        assert np.array_equal(a.pdf(wi, wo, rng, mode), b.pdf(wi, wo, rng, mode))
        sa = a.sample(wi, np.random.default_rng(3), mode)
        sb = b.sample(wi, np.random.default_rng(3), mode)
        assert all(np.array_equal(x, y) for x, y in zip(sa, sb))


def test_walk_cap_hits_are_counted():
    d = {"type": "layered", "max_vertices": 6,
         "interfaces": [{"type": "dielectric", "ior": 1.5}, {"type": "diffuse", "color": 1.0}],
         "media": [{"sigma_t": 8.0, "albedo": 1.0}]}
    mat = load(d)
    global_stats.take()
    n = 2000
    b = bind(mat, n)
    b.sample(np.repeat(direction(20.0)[None], n, axis=0), np.random.default_rng(0), want_pdf=False)
    hits = b.stats["cap_hits"]
    assert hits > 0 and mat.stats["cap_hits"] == hits
    assert global_stats.take().get("layered_walk_cap_hits") == hits


ALL = dict(STACKS, nested=REFERENCE_NESTED_UNI, smooth=LOSSLESS,
           coated={"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5},
                                                     {"type": "conductor", "metal": "Ag", "roughness": 0.0}],
                   "media": [{"sigma_t": 0.3, "albedo": [0.2, 0.4, 0.9]}]})


@pytest.mark.parametrize("name", list(ALL))
def test_no_nan_or_inf_for_any_direction(name):
    mat = load(ALL[name])
    rng = np.random.default_rng(5)
    n = 600
    wi, wo = uniform_sphere(rng, n), uniform_sphere(rng, n)
    # Exactly grazing, nearly grazing, normal, and opposite directions.
    wi[:4] = [[1, 0, 0], [np.sqrt(1 - 1e-24), 0, 1e-12], [0, 0, 1], [0, 0, -1]]
    wo[:4] = [[0, 1, 0], [0, 0, 1], [np.sqrt(1 - 1e-24), 0, -1e-12], [0, 0, 1]]
    b = bind(mat, n)
    for est in ("uni", "bi"):
        for mode in (RADIANCE, IMPORTANCE):
            f = b.eval(wi, wo, rng, mode, estimator=est)
            assert np.all(np.isfinite(f)) and np.all(f >= 0)
    for kind in ("lobes", "approx", "stochastic"):
        p = b.pdf(wi, wo, rng, kind=kind)
        assert np.all(np.isfinite(p)) and np.all(p >= 0)
    s = b.sample(wi, rng)
    for x in (s.wo, s.weight, s.pdf):
        assert np.all(np.isfinite(x))
    assert np.all(s.weight >= 0)
    alb = b.albedo()
    assert alb.shape == (n, 3) and np.all(np.isfinite(alb))
    if not mat.transmissive:
        below = wi[:, 2] <= 0
        assert np.all(b.eval(wi, wo, rng)[below] == 0) and np.all(s.weight[below] == 0)


def test_textured_medium_parameters_per_lane(tmp_path):
    """A texture on the medium albedo binds per lane: lanes at either texel give the same albedo
    as the constant material with that texel's value."""
    import OpenImageIO as oiio
    path = tmp_path / "albedo.exr"
    pixels = np.array([[[0.2, 0.2, 0.2], [0.9, 0.7, 0.5]]], dtype=np.float32)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(2, 1, 3, oiio.FLOAT))
    out.write_image(pixels)
    out.close()
    from backend.scene.reader import LoadContext, Node, dispatch
    from backend.materials import load_all

    def material(albedo):
        d = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.1},
                                               {"type": "diffuse", "color": 0.8}],
             "media": [{"sigma_t": 2.0, "albedo": albedo, "phase": {"type": "hg", "g": 0.2}}]}
        return dispatch(Node(d, "", LoadContext("<t>", tmp_path)), load_all())

    tex = material({"texture": "albedo.exr"})
    assert tex.uses_textures
    n = 40_000
    uv = np.repeat([[0.25, 0.5], [0.75, 0.5]], n, axis=0)
    wi = np.repeat(direction(30.0)[None], 2 * n, axis=0)
    s = tex.bind(ShadingContext(uv)).sample(wi, np.random.default_rng(2), IMPORTANCE, want_pdf=False)
    for k, value in enumerate(([0.2, 0.2, 0.2], [0.9, 0.7, 0.5])):
        ref = bind(material(value), n).sample(wi[:n], np.random.default_rng(3), IMPORTANCE, want_pdf=False)
        a, b = s.weight[k * n:(k + 1) * n], ref.weight
        se = np.sqrt(a.var(0) / n + b.var(0) / n)
        assert np.all(np.abs(a.mean(0) - b.mean(0)) <= 4 * se), (a.mean(0), b.mean(0))
