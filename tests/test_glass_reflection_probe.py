"""Smooth glass connects its mirror direction to the lights at every sample
(kernels/integrator.py ``_probe_reflection``) instead of only in the ~4 % of samples whose Fresnel
choice reflects. The estimate must stay the same — compared with the renderer with the
connection switched off, region by region, within the renders' own standard errors — and its
noise where the glass mirrors a light must fall. The scene mirrors every kind of emitter a ray
can meet: an area light and a sun disk (taken by the connection), an emitting mesh (left to the
mirror ray) and the world. No floor: its caustics behind the glass would be most of the noise,
and the connection does nothing for them. The same for the smooth top of a coated kind (closed
form, table), whose sampler takes the top's mirror by a random number too."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

import backend.integrator as integrator
from render_util import front_perspective, look_down_ortho, quad, region_z, render, scene
from stats_util import sidak

BLOCKS = 4


GLASS = {"type": "dielectric", "ior": 1.5, "roughness": 0.0}


def _glass_scene(spp: int, seed: int, max_bounces: int = 6, panel: bool = True, glass: dict = GLASS) -> dict:
    materials = {"glass": glass,
                 "glow": {"type": "emission", "color": [1.0, 0.8, 0.6], "strength": 20.0}}
    meshes = {"ball": {"shape": "sphere", "radius": 1.0, "segments": 64},
              "panel": quad([1.6, -2.4, 0.0], [0.3, 0.2, 0.0], [0.0, 0.0, 0.3])}
    objects = [{"name": "ball", "mesh": "ball", "materials": ["glass"]},
               {"name": "panel", "mesh": "panel", "materials": ["glow"]}][:2 if panel else 1]
    lights = [{"type": "area", "shape": "square", "size": 1.5, "power": 200.0,
               "to_world": [[1, 0, 0, -1], [0, 1, 0, -2], [0, 0, 1, 3], [0, 0, 0, 1]]},
              {"type": "sun", "strength": 2.0, "angle": 10.0,
               "to_world": [[1, 0, 0, 0], [0, 0.8, -0.6, 0], [0, 0.6, 0.8, 10], [0, 0, 0, 1]]}]
    return scene(24, 24, front_perspective(5.0, 0.25), materials, meshes, objects, lights,
                 world={"type": "constant", "color": [0.3, 0.35, 0.4]},
                 render={"spp": spp, "max_bounces": max_bounces, "seed": seed})


@pytest.fixture
def probe_off(monkeypatch):
    """The renderer with the mirror connection off: every light seen by reflection is found by
    the Fresnel-chosen mirror ray alone (the estimator before the connection)."""
    init = integrator.PathTracer.__init__

    def without_probe(self, *args, **kwargs):
        init(self, *args, **kwargs)
        self.settings = self.settings._replace(probed=np.zeros(0, np.bool_))

    monkeypatch.setattr(integrator.PathTracer, "__init__", without_probe)


def _render(spp: int, seed: int, **shape):
    return render(_glass_scene(spp, seed, **shape))


# A smooth top over a diffuse body (closed form: kernels/bsdf/coated_diffuse.py) and over a
# rough metal (a table: kernels/bsdf/tabulated.py): their samplers take the top's mirror with
# probability ≥ 20 % at weight F/that, the same choice.
def _coated(top_roughness: float, body: dict) -> dict:
    """A dielectric top (index 1.5) over ``body`` with an empty slab between."""
    return {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": top_roughness}, body],
            "media": [{"thickness": 1.0, "sigma_t": 0.0}]}


DIFFUSE_BODY = {"type": "diffuse", "color": [0.6, 0.2, 0.1]}
GOLD_BODY = {"type": "conductor", "metal": "Au", "roughness": 0.3}
COATED_DIFFUSE = _coated(0.0, DIFFUSE_BODY)
COATED_METAL = _coated(0.0, GOLD_BODY)
# Sharp but rough tops (α ≤ SHARP_ALPHA: glossy plastic, a clear coat): the lights a direction
# drawn from the top's lobe alone meets, at every sample (``_probe_lobe``), instead of in the
# ≥ 20 % of samples whose choice takes that lobe.
SHARP_COATED_DIFFUSE = _coated(0.004, DIFFUSE_BODY)
SHARP_COATED_METAL = _coated(0.01, GOLD_BODY)
KINDS = {"glass": GLASS,
         # a Mix Shader picks the glass in half the hits (throughput × 2)
         "mix": {"type": "mix", "factor": 0.5, "materials": [GLASS, {"type": "diffuse", "color": [0.5, 0.5, 0.5]}]},
         "coated-diffuse": COATED_DIFFUSE, "coated-metal": COATED_METAL,
         "sharp-coated-diffuse": SHARP_COATED_DIFFUSE, "sharp-coated-metal": SHARP_COATED_METAL}


@pytest.mark.parametrize("glass", list(KINDS.values()), ids=list(KINDS))
def test_glass_mirror_connection_keeps_the_image(request, glass):
    on = _render(64, 3, glass=glass)
    request.getfixturevalue("probe_off")
    off = _render(64, 4, glass=glass)
    z = region_z(on, off, BLOCKS)
    # all regions and channels together at a family-wise level of 0.1 %
    bound = norm.isf(sidak(1e-3, z.size) / 2.0)
    assert z.max() < bound, (z.max(), bound)


@pytest.mark.parametrize("glass, bound", [(GLASS, 0.2), (COATED_DIFFUSE, 0.3), (COATED_METAL, 0.3),
                                          (SHARP_COATED_DIFFUSE, 0.35), (SHARP_COATED_METAL, 0.55)],
                         ids=["glass", "coated-diffuse", "coated-metal", "sharp-coated-diffuse", "sharp-coated-metal"])
def test_glass_mirror_connection_lowers_the_noise(request, glass, bound):
    """Direct light only (max_bounces 0) and no emitting panel: the light the glass reflects is
    all the noise there is, besides the world's Fresnel choice (left as it was) and where each
    sample lands in its pixel (a 10° sun mirrored in the ball is a spot under a pixel wide). A
    coat's body adds its own light-sampling noise, which the connection leaves as it was.
    Measured ratios: glass 0.11, coated diffuse 0.14, coated metal 0.19."""
    shape = dict(max_bounces=0, panel=False, glass=glass)
    on = _render(32, 5, **shape)
    var_on = on.film.variance_of_mean()
    request.getfixturevalue("probe_off")
    off = _render(32, 5, **shape)
    var_off = off.film.variance_of_mean()
    ratio = float(var_on.sum() / var_off.sum())
    assert ratio < bound, ratio


def _tilted_plane(material: dict, spp: int, seed: int, sun_angle: float = 20.0) -> dict:
    """A plane at 45° seen from above, mirroring a sun on the horizon into every pixel: the light
    a sharp top reflects is most of the image (direct light only)."""
    sun = {"type": "sun", "strength": 2.0, "angle": sun_angle,
           "to_world": [[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]]}   # shines towards +y
    return scene(16, 16, look_down_ortho(0.5), {"m": material},
                 {"plane": quad([0, 0, 0], [1.2, 0, 0], [0, 0.85, 0.85])}, [{"mesh": "plane", "materials": ["m"]}],
                 [sun], world={"type": "constant", "color": [0.2, 0.2, 0.2]},
                 render={"spp": spp, "max_bounces": 0, "seed": seed})


# The third: a lobe at SHARP_ALPHA (α 0.02, the bluntest that is probed), about as wide as a 2° sun, so that light sampling takes a fair share of the highlight and the two
# strategies' weights both matter.
BLUNT = _coated(0.02, {"type": "diffuse", "color": [0.2, 0.3, 0.6]})


@pytest.mark.parametrize("material, sun", [(SHARP_COATED_DIFFUSE, 20.0), (SHARP_COATED_METAL, 20.0), (BLUNT, 2.0)],
                         ids=["diffuse", "metal", "lobe-as-wide-as-the-sun"])
def test_sharp_top_connection_keeps_the_mirrored_sun(request, material, sun):
    on = render(_tilted_plane(material, 64, 7, sun))
    request.getfixturevalue("probe_off")
    off = render(_tilted_plane(material, 64, 8, sun))
    z = region_z(on, off, 2)
    bound = norm.isf(sidak(1e-3, z.size) / 2.0)
    assert z.max() < bound, (z.max(), bound)
