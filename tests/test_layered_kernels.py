"""The layered walk's interfaces and slabs (compiled: backend/kernels/layered/iface.py, walk.py)
against the standard materials (backend/materials) and media (layered/medium.py), and their
samplers against their pdfs."""
import numpy as np
import pytest

from backend.kernels.layered import iface as ki
from backend.layered.medium import Medium, MediumSpec
from backend.layered.phase import HenyeyGreenstein, MicroflakeFiber, PhaseSpec
from backend.layered.probe import (iface_eval, iface_sample, interface_block, layered_with_medium,
                                   slab_depth_density, slab_flights, slab_transmittance)
from backend.materials.base import IMPORTANCE
from backend.textures import ConstantParam
from backend.materials.conductor import ConductorMaterial
from backend.materials.dielectric import DielectricMaterial
from backend.materials.diffuse import DiffuseMaterial
from backend.materials.base import ShadingContext
from stats_util import SIGNIFICANCE, Grid, chi2_test, sidak

N = 4000


def random_dirs(rng, n, lower=True):
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    if not lower:
        v[:, 2] = np.abs(v[:, 2])
    return v


def bind(material, n=N):
    return material.bind(ShadingContext(np.zeros((n, 2))))


MATERIALS = {
    "dielectric-ggx-aniso": DielectricMaterial(ior=1.5, ior_above=1.2, roughness=0.3, roughness_v=0.1),
    "dielectric-beckmann-sep": DielectricMaterial(ior=1.33, roughness=0.2, distribution="beckmann",
                                                  masking="separable"),
    "dielectric-dense-above": DielectricMaterial(ior=1.0, ior_above=1.5, roughness=0.15),
    "conductor-ggx": ConductorMaterial.named("Cu", roughness=0.2, roughness_v=0.4, eta_above=1.5),
    "conductor-beckmann-sep": ConductorMaterial.named("Au", roughness=0.1, distribution="beckmann",
                                                      masking="separable"),
    "diffuse": DiffuseMaterial([0.2, 0.5, 0.9]),
}


@pytest.mark.parametrize("name", list(MATERIALS))
def test_kernel_values_equal_material_bsdf(name):
    rng = np.random.default_rng(1)
    bsdf = bind(MATERIALS[name])
    ker = interface_block(MATERIALS[name])
    lower = name.startswith("dielectric")
    wi = random_dirs(rng, N, lower)
    wo = random_dirs(rng, N, lower)
    val, pf, pr = iface_eval(ker, wi, wo)
    ref = bsdf.eval(wi, wo, rng, IMPORTANCE)
    assert np.allclose(val, ref, rtol=1e-9, atol=1e-12)
    assert np.all(np.isfinite(val)) and np.all(np.isfinite(pf)) and np.all(np.isfinite(pr))
    if "beckmann" not in name:
        # Same sampler (visible normals / cosine) as the material: the same densities.
        assert np.allclose(pf, bsdf.pdf(wi, wo, rng, IMPORTANCE), rtol=1e-9, atol=1e-12)
        assert np.allclose(pr, bsdf.pdf(wo, wi, rng, IMPORTANCE), rtol=1e-9, atol=1e-12)


CHI2_CASES = [(name, theta) for name in MATERIALS for theta in (20.0, 70.0)] + \
             [("dielectric-ggx-aniso", 160.0), ("dielectric-dense-above", 135.0)]


@pytest.mark.parametrize("name,theta", CHI2_CASES)
def test_kernel_sampler_matches_its_pdf(name, theta):
    """Chi-square of the kernel's sampler against the kernel's forward density, the sample
    weight equal to value/pdf, and the reverse density equal to the forward one of the swap."""
    n = 100_000
    rng = np.random.default_rng(7)
    t = np.radians(theta)
    wi1 = np.array([np.sin(t) * np.cos(0.3), np.sin(t) * np.sin(0.3), np.cos(t)])
    ker = interface_block(MATERIALS[name])
    wi = np.repeat(wi1[None], n, axis=0)
    wo, w, pf, pr, delta = iface_sample(ker, wi, rng)
    ok = pf > 0  # samples that produced a direction (some may carry weight 0: masking)

    def pdf(dirs):
        m = dirs.shape[0]
        return iface_eval(ker, np.repeat(wi1[None], m, axis=0), dirs)[1]

    res = chi2_test(wo[ok], n, pdf, Grid(16, 32))
    assert res.p_value > sidak(SIGNIFICANCE, len(CHI2_CASES)), str(res)
    val, f, r = iface_eval(ker, wi[ok], wo[ok])
    assert np.allclose(w[ok], val / f[:, None], rtol=1e-9)
    assert np.allclose(f, pf[ok], rtol=1e-9) and np.allclose(r, pr[ok], rtol=1e-9)
    _, f_swap, _ = iface_eval(ker, wo[ok], wi[ok])
    assert np.allclose(r, f_swap, rtol=1e-9, atol=1e-300)


def test_smooth_kernels_are_delta_with_material_weights():
    rng = np.random.default_rng(3)
    wi = random_dirs(rng, N)
    for mat in (DielectricMaterial(ior=1.5, ior_above=1.2),
                ConductorMaterial.named("Cu", roughness=0.0, eta_above=1.5)):
        bsdf = bind(mat)
        ker = interface_block(mat)
        assert ker[0, ki.IF_DELTA] > 0
        w_in = wi if isinstance(mat, DielectricMaterial) else np.abs(wi)
        wo, w, pf, pr, delta = iface_sample(ker, w_in, np.random.default_rng(5))
        s = bsdf.sample(w_in, np.random.default_rng(6), IMPORTANCE)
        assert delta.all() and s.delta.all()
        # Where both chose the same lobe (same side), the same direction and weight.
        same = (wo[:, 2] > 0) == (s.wo[:, 2] > 0)
        assert same.mean() > 0.5
        assert np.allclose(wo[same], s.wo[same]) and np.allclose(w[same], s.weight[same])
        # The lobe frequencies agree (binomial standard error).
        p_k, p_m = np.mean(wo[:, 2] * w_in[:, 2] > 0), np.mean(s.wo[:, 2] * w_in[:, 2] > 0)
        assert abs(p_k - p_m) <= 4.0 * np.sqrt(2 * max(p_m * (1 - p_m), 1e-4) / N)


def _spec(thickness, sigma_t, albedo, phase_spec, grey):
    return MediumSpec(ConstantParam(thickness, 1),
                      ConstantParam(sigma_t, 1 if np.ndim(sigma_t) == 0 else 3),
                      ConstantParam(np.broadcast_to(albedo, (3,)).copy(), 3), phase_spec, grey)


MEDIA = {
    "grey-hg": lambda: (Medium(2.0, 0.7, [0.3, 0.6, 0.9], HenyeyGreenstein(0.4)),
                        _spec(2.0, 0.7, [0.3, 0.6, 0.9],
                              PhaseSpec("hg", HenyeyGreenstein, {"g": ConstantParam(0.4, 1)}, False), True)),
    "rgb": lambda: (Medium(1.0, [0.2, 1.0, 3.0], 0.8, HenyeyGreenstein(-0.2)),
                    _spec(1.0, [0.2, 1.0, 3.0], 0.8,
                          PhaseSpec("hg", HenyeyGreenstein, {"g": ConstantParam(-0.2, 1)}, False), False)),
    "microflake": lambda: (Medium(1.0, 1.5, 0.9, MicroflakeFiber(0.1, [[0.6, 0.0, 0.8]])),
                           _spec(1.0, 1.5, 0.9,
                                 PhaseSpec("microflake", MicroflakeFiber,
                                           {"stddev": ConstantParam(0.1, 1),
                                            "orientation": ConstantParam([0.6, 0.0, 0.8], 3)}, True), True)),
}


@pytest.mark.parametrize("name", list(MEDIA))
def test_slab_ops_equal_medium(name):
    rng = np.random.default_rng(11)
    med, spec = MEDIA[name]()
    ops = bind(layered_with_medium(spec), 1)     # slab 0 of a null / medium / null stack
    n = 3000
    d = random_dirs(rng, n)
    s0 = rng.random(n)
    s1 = np.where(rng.random(n) < 0.2, np.where(d[:, 2] > 0, 0.0, 1.0), rng.random(n))
    T = slab_transmittance(ops, 0, d, s0, s1)
    assert np.allclose(T, med.transmittance(d, s0, s1), rtol=1e-12, atol=1e-300)
    to_med = rng.random(n) < 0.5
    assert np.allclose(slab_depth_density(ops, 0, d, s0, s1, to_med), med.free_flight_pdf(s0, s1, d, to_med),
                       rtol=1e-12, atol=1e-300)
    # Free flights: the reported density is the density of the depth produced, and the weights
    # are finite and non-negative.
    new_s, sc, w, pdf = slab_flights(ops, 0, s0, d, rng)
    alive = np.abs(d[:, 2]) >= 1e-7
    assert np.allclose(pdf[alive], slab_depth_density(ops, 0, d, s0, new_s, sc)[alive], rtol=1e-12)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
