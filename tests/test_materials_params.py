"""Textured parameters, take(), scene-file parsing of the standard materials, emission."""
from __future__ import annotations

import numpy as np
import pytest

from backend.errors import SceneError
from backend.materials import load_all
from backend.materials.base import IMPORTANCE, RADIANCE, ShadingContext
from backend.materials.conductor import ConductorMaterial
from backend.materials.dielectric import DielectricMaterial
from backend.materials.diffuse import DiffuseMaterial
from backend.materials.emission import EmissionMaterial
from backend.scene.reader import LoadContext, Node, dispatch
from backend.textures import ImageParam

CTX1 = ShadingContext(np.zeros((1, 2)))


def image(rng, channels, lo, hi, zero_block=False):
    tex = rng.uniform(lo, hi, (4, 5, channels)).astype(np.float32)
    if zero_block:   # bilinear lookups inside this block are exactly 0: smooth (delta) lanes
        tex[:3, :3] = 0.0
    return ImageParam(tex, channels, np.ones(3) if channels == 3 else np.asarray(1.0), "test")


def random_dirs(rng, n):
    w = rng.normal(size=(n, 3))
    return w / np.linalg.norm(w, axis=1, keepdims=True)


def textured_and_constant(kind, rng):
    """A material with every parameter textured, and a factory for the lane's constant twin."""
    if kind == "diffuse":
        p = {"color": image(rng, 3, 0, 1)}
        return DiffuseMaterial(**p), p, lambda v: DiffuseMaterial(**v)
    if kind == "conductor":
        rough = image(rng, 1, 0.05, 0.8, zero_block=True)
        p = {"eta": image(rng, 3, 0.1, 3), "k": image(rng, 3, 0.5, 5), "roughness": rough,
             "roughness_v": ImageParam(rough.texels * 0.5, 1, np.asarray(1.0), "v"),
             "tint": image(rng, 3, 0.2, 1)}
        return (ConductorMaterial(**p, distribution="beckmann", eta_above=1.3), p,
                lambda v: ConductorMaterial(**v, distribution="beckmann", eta_above=1.3))
    rough = image(rng, 1, 0.05, 0.8, zero_block=True)
    p = {"ior": image(rng, 1, 1.1, 2.5), "roughness": rough,
         "roughness_v": ImageParam(rough.texels * 0.7, 1, np.asarray(1.0), "v"),
         "transmission_color": image(rng, 3, 0.2, 1)}
    return (DielectricMaterial(**p, ior_above=1.2), p,
            lambda v: DielectricMaterial(**v, ior_above=1.2))


@pytest.mark.parametrize("kind", ["diffuse", "conductor", "dielectric"])
def test_textured_lanes_match_constants(kind):
    rng = np.random.default_rng(17)
    mat, params, twin = textured_and_constant(kind, rng)
    assert mat.uses_textures
    n = 60
    uv = rng.random((n, 2))
    bsdf = mat.bind(ShadingContext(uv))
    wi, wo = random_dirs(rng, n), random_dirs(rng, n)
    for mode in (RADIANCE, IMPORTANCE):
        ev = bsdf.eval(wi, wo, rng, mode)
        pd = bsdf.pdf(wi, wo, rng, mode)
        s = bsdf.sample(wi, rng, mode)
        albedo = np.broadcast_to(bsdf.albedo(), (n, 3))
        for i in range(n):
            const = twin({k: p.bind(uv[i:i + 1])[0] for k, p in params.items()}).bind(CTX1)
            sl = slice(i, i + 1)
            np.testing.assert_allclose(ev[sl], const.eval(wi[sl], wo[sl], rng, mode), rtol=1e-12)
            np.testing.assert_allclose(pd[sl], const.pdf(wi[sl], wo[sl], rng, mode), rtol=1e-12)
            np.testing.assert_allclose(albedo[sl], np.broadcast_to(const.albedo(), (1, 3)),
                                       rtol=1e-12)
            if s.delta[i]:
                assert const.has_delta and const.delta_only
            elif s.pdf[i] > 0:
                f = const.eval(wi[sl], s.wo[sl], rng, mode)
                p = const.pdf(wi[sl], s.wo[sl], rng, mode)
                np.testing.assert_allclose(s.pdf[i], p[0], rtol=1e-9)
                np.testing.assert_allclose(s.weight[sl], f / p[0], rtol=1e-9)
    if kind != "diffuse":
        assert bsdf.has_delta and not bsdf.delta_only   # the texture mixes smooth and rough lanes


@pytest.mark.parametrize("kind", ["diffuse", "conductor", "dielectric"])
def test_take_subsets_lanes(kind):
    rng = np.random.default_rng(5)
    mat, _, _ = textured_and_constant(kind, rng)
    n = 40
    uv = rng.random((n, 2))
    bsdf = mat.bind(ShadingContext(uv))
    wi, wo = random_dirs(rng, n), random_dirs(rng, n)
    idx = np.array([3, 7, 8, 20, 39])
    mask = np.zeros(n, dtype=bool)
    mask[idx] = True
    for sub in (bsdf.take(idx), bsdf.take(mask)):
        assert sub.n == idx.size
        np.testing.assert_allclose(sub.eval(wi[idx], wo[idx], rng), bsdf.eval(wi, wo, rng)[idx])
        np.testing.assert_allclose(sub.pdf(wi[idx], wo[idx], rng), bsdf.pdf(wi, wo, rng)[idx])
    # Constants stay constants (shape () / (1, 3)) under take().
    const = {"diffuse": DiffuseMaterial(0.5), "conductor": ConductorMaterial.named("Au"),
             "dielectric": DielectricMaterial()}[kind].bind(ShadingContext(uv))
    t = const.take(idx)
    for name in ("color", "eta", "k", "tint", "alpha_u"):
        if hasattr(t, name):
            assert np.ndim(getattr(t, name)) == 0 or np.shape(getattr(t, name))[0] == 1


# ---------------------------------------------------------------------------------- parsing
def parse(value, tmp_path=None):
    ctx = LoadContext("scene.json", tmp_path)
    return dispatch(Node(value, "materials.m", ctx), load_all())


def test_parse_standard_materials():
    m = parse({"type": "conductor", "metal": "Au", "roughness": 0.2, "roughness_v": 0.05,
               "distribution": "beckmann", "masking": "separable", "eta_above": 1.5})
    assert isinstance(m, ConductorMaterial) and m.two_sided and m.eta_above == 1.5
    m = parse({"type": "conductor", "eta": [0.2, 0.9, 1.1], "k": 3.0, "roughness": 0})
    assert m.bind(CTX1).delta_only
    m = parse({"type": "dielectric", "ior": 1.33, "roughness": 0.1,
               "transmission_color": [1, 0.9, 0.8]})
    assert isinstance(m, DielectricMaterial) and not m.two_sided
    assert parse({"type": "dielectric"}).bind(CTX1).delta_only     # smooth by default
    m = parse({"type": "diffuse", "color": 0.3})
    np.testing.assert_allclose(m.bind(CTX1).albedo(), [[0.3, 0.3, 0.3]])
    m = parse({"type": "emission", "color": [1, 0.5, 0.25], "strength": 4})
    assert isinstance(m, EmissionMaterial)
    np.testing.assert_allclose(m.emission.bind(np.zeros((2, 2))).reshape(-1, 3)[0], [4, 2, 1])
    b = m.bind(CTX1)
    assert b.delta_only
    s = b.sample(np.array([[0.0, 0.0, 1.0]]), np.random.default_rng(0))
    assert np.all(s.weight == 0)


@pytest.mark.parametrize("kind", ["diffuse", "conductor", "dielectric"])
def test_every_material_accepts_emission(kind):
    m = parse({"type": kind, "emission": [2.0, 1.0, 0.0]})
    np.testing.assert_allclose(m.emission.bind(np.zeros((1, 2))).reshape(3), [2, 1, 0])
    assert parse({"type": kind, "emission": 0}).emission is None
    assert parse({"type": kind}).emission is None


@pytest.mark.parametrize("value,path,text", [
    ({"type": "conductor", "metal": "Xx"}, "materials.m.metal", "unknown metal 'Xx'"),
    ({"type": "conductor", "eta": 1.0}, "materials.m.k", "together"),
    ({"type": "conductor", "metal": "Au", "k": 1.0}, "materials.m.metal", "not both"),
    ({"type": "conductor", "roughness": -0.3}, "materials.m.roughness", "expected a number in [0, 1]"),
    ({"type": "conductor", "distribution": "phong"}, "materials.m.distribution", "expected one of"),
    ({"type": "conductor", "eta_above": 0}, "materials.m.eta_above", "> 0"),
    ({"type": "dielectric", "ior": 0}, "materials.m.ior", "> 0"),
    ({"type": "dielectric", "rougness": 0.1}, "materials.m.rougness", "unknown field"),
    ({"type": "diffuse", "color": [1, -2, 3]}, "materials.m.color[1]", ">= 0"),
    ({"type": "conductor", "tint": -1}, "materials.m.tint[0]", ">= 0"),
    ({"type": "emission", "strength": -1}, "materials.m.strength", ">= 0"),
    ({"type": "diffuse", "emission": [1, -1, 0]}, "materials.m.emission[1]", ">= 0"),
    ({"type": "diffuse", "color": {"texture": "missing.png"}}, "materials.m.color.texture", "not found"),
])
def test_parse_errors_name_the_field(value, path, text, tmp_path):
    from backend.scene.reader import MISSING_TEXTURES
    strict = MISSING_TEXTURES.set("error")      # a missing texture is an error here (else magenta)
    try:
        with pytest.raises(SceneError) as err:
            parse(value, tmp_path)
    finally:
        MISSING_TEXTURES.reset(strict)
    msg = str(err.value)
    assert msg.startswith(f"scene.json: {path}: "), msg
    assert text in msg, msg


def test_textured_roughness_from_file(tmp_path):
    import OpenImageIO as oiio
    pixels = np.array([[[0.0], [0.5]], [[0.25], [1.0]]], dtype=np.float32)
    out = oiio.ImageOutput.create(str(tmp_path / "rough.exr"))
    out.open(str(tmp_path / "rough.exr"), oiio.ImageSpec(2, 2, 1, oiio.FLOAT))
    out.write_image(pixels)
    out.close()
    m = parse({"type": "conductor", "metal": "Cu", "roughness": {"texture": "rough.exr"}}, tmp_path)
    assert m.uses_textures
    uv = np.array([[0.25, 0.75], [0.75, 0.75], [0.25, 0.25], [0.75, 0.25]])  # texel centres
    b = m.bind(ShadingContext(uv))
    np.testing.assert_allclose(b.alpha_u, [0.0, 0.5, 0.25, 1.0])
    np.testing.assert_array_equal(b.smooth, [True, False, False, False])
