"""The Principled mapping (addon/export/principled.py) against Lamina's own layered BSDF.

1. The table's Lamina half and the exact relation the mapping inverts: a dielectric over a
   Lambertian body reflects R + T·ρT↓/(1 − ρR↓) under uniform light; checked against Monte Carlo
   estimates of the layered BSDF (not the code the table came from) at points between the grid
   nodes (so interpolation is checked too).
2. The stacks the mapping writes for Principled settings reflect, under uniform light, the albedo
   it targets (Cycles', from the table's measured half): within 2 % plus 4 standard errors.
   (Cycles itself is compared in tests/blender/test_principled_parity.py.)
No bpy: principled.py is loaded on its own.
"""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from backend.materials import load_all
from backend.materials.base import IMPORTANCE, ShadingContext
from backend.scene.reader import LoadContext, Node, dispatch

ROOT = Path(__file__).resolve().parent.parent
K_SIGMA = 4.0


def principled():
    spec = importlib.util.spec_from_file_location("lamina_principled", ROOT / "addon" / "export" / "principled.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


P = principled()


def material(doc):
    ctx = LoadContext("<test>")
    ctx.cache["layered_defaults"] = {}
    return dispatch(Node(doc, "", ctx), load_all())


def uniform_light_albedo(doc, n, seed):
    """Albedo under uniform light: viewing directions cosine-distributed (cos²θ uniform), mean
    of the reflected sample weights; its standard error."""
    rng = np.random.default_rng(seed)
    mu2 = rng.random(n)
    wi = np.stack([np.sqrt(1 - mu2), np.zeros(n), np.sqrt(mu2)], axis=1)
    b = material(doc).bind(ShadingContext(np.full((n, 2), 0.5)))
    kw = {"want_pdf": False} if getattr(b, "stochastic", False) else {}
    s = b.sample(wi, rng, IMPORTANCE, **kw)
    w = np.where(np.isfinite(s.weight), s.weight, 0.0) * (s.wo[:, 2] > 0)[:, None]
    return w.mean(axis=0), w.std(axis=0, ddof=1) / np.sqrt(n)


def test_table_shape_and_provenance():
    t = P.table()
    assert t["format"] == "lamina-principled-table" and t["bins"] == 8
    n_ior, n_r, b = len(t["ior"]), len(t["roughness"]), t["bins"]
    for key in ("cycles_specular", "cycles_specular_untinted_part", "lamina_R", "lamina_T"):
        assert t[key].shape == (n_ior, n_r, b), key
    assert t["cycles_metal"].shape == t["lamina_conductor"].shape == (len(t["f0"]), n_r, b)
    # Physical sanity of the measured half: reflectances in [0, 1], the tint-0 part below the layer,
    # and Cycles' metal of F0 = 1 reflects everything (its multiscatter GGX keeps the energy).
    assert np.all((t["cycles_specular"] >= 0) & (t["cycles_specular"] <= 1))
    assert np.all(t["cycles_specular_untinted_part"] <= t["cycles_specular"] + 0.01)
    assert np.all(np.abs(t["cycles_metal"][-1].mean(axis=1) - 1.0) < 0.01)
    # Energy: the Lamina interface never reflects + transmits more than it receives.
    assert np.all(t["lamina_R"] + t["lamina_T"] <= 1.0 + 0.01)


@pytest.mark.parametrize("estimator", ["bi", "auto"])        # the random walk, and the closed form
@pytest.mark.parametrize("ior,roughness,rho", [(1.5, 0.5, 0.8), (1.33, 0.25, 0.3), (2.2, 0.75, 1.1),
                                               (1.62, 0.05, 0.6)])
def test_exact_relation_matches_the_layered_bsdf(ior, roughness, rho, estimator):
    itf = P.interface(ior, roughness)
    predicted = P.stack_albedo([rho] * 3, itf).mean(axis=1)[0]
    doc = {"type": "layered", "estimator": estimator,
           "interfaces": [{"type": "dielectric", "ior": ior, "roughness": roughness ** 2},
                          {"type": "diffuse", "color": [rho] * 3}],
           "media": [{"thickness": 1.0, "sigma_t": 0.0}]}
    mean, se = uniform_light_albedo(doc, 80000, 11)
    # Table noise (40 000 samples per bin) and bilinear interpolation: 1 % relative.
    assert abs(mean[0] - predicted) <= K_SIGMA * se[0] + 0.01 * predicted, (mean[0], predicted, se[0])


CASES = {
    "default grey": {},
    "red, rough": {"base_color": (0.8, 0.1, 0.05), "roughness": 0.8},
    "blue, smooth, IOR 2": {"base_color": (0.1, 0.3, 0.9), "roughness": 0.1, "ior": 2.0},
    "specular level and tint": {"base_color": (0.5, 0.5, 0.5), "specular_ior_level": 0.8,
                                "specular_tint": (1.0, 0.5, 0.2)},
    "coat": {"base_color": (0.2, 0.6, 0.2), "roughness": 0.5, "coat_weight": 1.0, "coat_roughness": 0.1},
    "tinted half coat": {"base_color": (0.7, 0.7, 0.7), "roughness": 0.3, "coat_weight": 0.5,
                         "coat_roughness": 0.05, "coat_tint": (0.9, 0.6, 0.4), "coat_ior": 1.6},
    "metallic 0.3": {"base_color": (0.9, 0.6, 0.2), "metallic": 0.3, "roughness": 0.4},
    "metal": {"base_color": (0.9, 0.6, 0.2), "metallic": 1.0, "roughness": 0.4},
    "coated rough plastic": {"base_color": (0.3, 0.5, 0.9), "roughness": 0.9, "coat_weight": 1.0,
                             "coat_roughness": 0.3, "coat_ior": 1.4},
    "sheen": {"base_color": (0.3, 0.1, 0.1), "sheen_weight": 1.0, "sheen_roughness": 0.5},
}


# Coated metals: the two-layer rule is cruder for a specular base (documented in docs/blender.md:
# within 4 % up to roughness 0.3, 8 % beyond; measured 0.2–3.6 % and 4–7.5 % on these); a target
# beyond what Lamina's single-scattering conductor reflects under a coat is clamped (and named in
# the render's warning).
COATED_METALS = {
    "coated metal": {"base_color": (0.95, 0.64, 0.54), "metallic": 1.0, "roughness": 0.3, "coat_weight": 1.0},
    "coated smooth metal": {"base_color": (0.5, 0.8, 0.3), "metallic": 1.0, "roughness": 0.1, "coat_weight": 1.0},
    "coated rough metal": {"base_color": (0.5, 0.8, 0.3), "metallic": 1.0, "roughness": 0.6, "coat_weight": 1.0,
                           "coat_roughness": 0.2},
}


@pytest.mark.parametrize("name", sorted(COATED_METALS))
def test_coated_metals_within_the_documented_bound(name):
    info = {}
    doc, notes = P.principled_material(COATED_METALS[name], info)
    mean, se = uniform_light_albedo(doc, 100000, 7)
    target = info["target"]
    bound = 0.04 if COATED_METALS[name]["roughness"] <= 0.3 else 0.08
    reachable = np.abs(mean - target) <= bound * target + K_SIGMA * se
    if any("clamped" in n for n in notes):
        assert np.any(mean < target * (1 - bound)), (name, mean, target)     # the clamp was needed
        assert np.all(reachable | (mean < target)), (name, mean, target)
    else:
        assert np.all(reachable), (name, mean, target, se)


# A very rough base under a rough coat: the two-layer rule's documented bound (docs/blender.md),
# measured +2.8 % on "coated rough plastic" (tabulated stack, 1e6 samples: 0.3743 against the
# walk's 0.3739 ± 0.0005 and the target 0.3637).
ROUGH_UNDER_ROUGH = {"coated rough plastic"}
ROUGH_UNDER_ROUGH_COAT = 0.03


@pytest.mark.parametrize("name", sorted(CASES))
def test_mapped_stack_has_the_targeted_albedo(name):
    info = {}
    doc, notes = P.principled_material(CASES[name], info)
    assert "clamped" not in " ".join(notes), notes
    mean, se = uniform_light_albedo(doc, 100000, 7)
    target = info["target"]
    bound = ROUGH_UNDER_ROUGH_COAT if name in ROUGH_UNDER_ROUGH else 0.02
    assert np.all(np.abs(mean - target) <= bound * target + K_SIGMA * se), (name, mean, target, se, doc)


def test_cycles_ior_remap_and_transmission_tint():
    assert P.cycles_ior(1.5, 0.5) == 1.5
    # Specular IOR Level 1 doubles F0 (Cycles' remapping), 0 switches the reflection off.
    assert P.f0_from_ior(P.cycles_ior(1.5, 1.0)) == pytest.approx(2 * P.f0_from_ior(1.5))
    assert P.cycles_ior(1.5, 0.0) == pytest.approx(1.0)
    glass, notes = P.principled_material({"transmission": 1.0, "base_color": (0.64, 0.81, 1.0), "ior": 1.45})
    assert glass["type"] == "dielectric" and glass["ior"] == pytest.approx(1.45)
    assert glass["transmission_color"] == pytest.approx([0.8, 0.9, 1.0])        # √base per crossing
    half, notes = P.principled_material({"transmission": 0.4})
    assert half["type"] == "layered" and any("Transmission Weight 0.4" in n for n in notes)
    mostly, notes = P.principled_material({"transmission": 0.6})
    assert mostly["type"] == "dielectric" and any("Transmission Weight 0.6" in n for n in notes)


def test_emission_is_attenuated_like_cycles_layers():
    plain, _ = P.principled_material({"emission": (2.0, 1.0, 0.5)})
    assert plain["emission"] == pytest.approx([2.0, 1.0, 0.5])
    coated, _ = P.principled_material({"emission": (2.0, 1.0, 0.5), "coat_weight": 1.0, "coat_roughness": 0.0})
    # Under a clear coat Cycles scales emission by 1 − the coat's albedo (≈ 0.91 for IOR 1.5).
    ratio = np.array(coated["emission"]) / [2.0, 1.0, 0.5]
    assert np.allclose(ratio, ratio[0]) and 0.88 < ratio[0] < 0.93
