"""The ``layered`` material schema: parsing, the IOR chain, options, errors naming the field."""
import numpy as np
import pytest

from backend.errors import SceneError
from backend.layered.bsdf import LayeredBSDF
from backend.layered.probe import describe
from backend.materials.metals import metal_ior
from layered_util import REFERENCE, REFERENCE_NESTED_UNI, bind, load


def test_reference_example_loads_as_written():
    mat = load(REFERENCE)
    assert mat.two_sided and not mat.transmissive
    assert mat.eta_slab == [1.5, 1.2] and mat.eta_top == 1.0
    b = bind(mat, 4)
    assert isinstance(b, LayeredBSDF)
    k0, k1, k2 = describe(b)["interfaces"]
    assert k0["kind"] == "dielectric" and np.isclose(k0["eta"], 1.5)
    assert k1["kind"] == "dielectric" and np.isclose(k1["eta"], 1.2 / 1.5)
    # The metal's Fresnel is relative to the coating it sits under (index 1.2).
    eta, k = metal_ior("Cu")
    assert k2["kind"] == "conductor"
    assert np.allclose(k2["eta"], np.asarray(eta).reshape(3) / 1.2) and np.allclose(k2["k"], np.asarray(k).reshape(3) / 1.2)
    assert [m["directional"] for m in describe(b)["media"]] == [True, True]


def test_ior_chain_with_null_and_nesting():
    d = {"type": "layered",
         "interfaces": [{"type": "dielectric", "ior": 1.4}, {"type": "null"},
                        {"type": "dielectric", "ior": 1.6, "roughness": 0.1}],
         "media": [{"sigma_t": 0.5}, {"sigma_t": 0.0}]}
    mat = load(d)
    assert mat.eta_slab == [1.4, 1.4] and mat.eta_bottom == 1.6 and mat.transmissive
    assert not mat.two_sided
    assert describe(bind(mat, 2))["interfaces"][1]["kind"] == "null"
    nested = load(REFERENCE_NESTED_UNI)
    inner = nested.interfaces[1]
    assert inner.eta_top == 1.5 and inner.eta_slab == [1.2]
    assert nested.options.estimator == "uni" and inner.options.estimator == "uni"


def test_options_from_scene_defaults_and_material():
    d = dict(REFERENCE)
    mat = load(d, defaults={"estimator": "uni", "pdf": "stochastic", "pdf_constant": 0.5})
    assert (mat.options.estimator, mat.options.pdf, mat.options.pdf_constant) == ("uni", "stochastic", 0.5)
    d = dict(REFERENCE, estimator="bi", max_vertices=64)
    mat = load(d, defaults={"estimator": "uni"})
    assert mat.options.estimator == "bi" and mat.options.max_vertices == 64
    plain = load(REFERENCE, defaults={})                 # no scene-level defaults: the schema's
    assert plain.options.estimator == "auto" and plain.options.pdf == "lobes"


def test_one_interface_and_constants():
    mat = load({"type": "layered", "interfaces": [{"type": "conductor", "metal": "Au"}]})
    assert type(bind(mat, 3)).__name__ == "ConductorBSDF"
    assert not load(REFERENCE).uses_textures


ERRORS = [
    ({"interfaces": []}, "interfaces: a layered material needs at least one interface"),
    ({"interfaces": [{"type": "diffuse"}, {"type": "dielectric"}], "media": [{}]},
     "interfaces[0]: interface 0 is opaque"),
    ({"interfaces": [{"type": "dielectric"}, {"type": "diffuse"}]}, "media: expected 1 media"),
    ({"interfaces": [{"type": "dielectric", "ior_above": 1.3}]}, "interfaces[0].ior_above: implied by the stack"),
    ({"interfaces": [{"type": "emission"}]}, "interfaces[0].type: expected one of"),
    ({"interfaces": [{"type": "dielectric", "ior": {"texture": "x.png"}}, {"type": "diffuse"}], "media": [{}]},
     "interfaces[0].ior"),
    ({"interfaces": [{"type": "dielectric", "roughnes": 0.1}]}, "interfaces[0].roughnes: unknown field"),
    ({"interfaces": [{"type": "dielectric"}, {"type": "diffuse"}], "media": [{"sigma_t": -1}]},
     "media[0].sigma_t"),
    ({"interfaces": [{"type": "dielectric"}], "estimator": "both"}, "estimator: expected one of 'auto', 'bi', 'uni'"),
    ({"interfaces": [{"type": "dielectric"}], "max_vertices": 1}, "max_vertices"),
    ({"interfaces": [{"type": "dielectric"}, {"type": "conductor", "eta_above": 2}], "media": [{}]},
     "interfaces[1].eta_above: implied by the stack"),
]


@pytest.mark.parametrize("extra,message", ERRORS)
def test_errors_name_the_field(extra, message):
    with pytest.raises(SceneError) as err:
        load({"type": "layered", **extra})
    assert message in str(err.value), str(err.value)


def test_scene_defaults_are_validated():
    with pytest.raises(SceneError) as err:
        load({"type": "layered", "interfaces": [{"type": "dielectric"}]}, defaults={"estimater": "uni"})
    assert "render.layered.estimater: unknown field" in str(err.value)
