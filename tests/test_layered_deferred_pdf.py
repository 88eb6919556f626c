"""The MIS pdf of a layered continuation, estimated only when its ray finds a light that light
sampling competes for (kernels/integrator.py ``defer_pdf``).

MIS stays unbiased only if the two strategies' weights add up to one for every path. The
independent reference is a render without next-event estimation (the light is not
light-sampled, so BSDF sampling alone finds it, weight 1): the MIS render must agree with it in
every region within Monte Carlo error, with the pdfs deferred (the default here) and estimated
at once (the integrator's choice when an environment map is light-sampled)."""
import numpy as np
import pytest

from backend.lights.point import PointLight
from layered_util import STACKS
from render_util import front_perspective, region_z, render, scene

# A sphere light large and close enough that many continuation rays hit it: its MIS weights
# matter in much of the image.
BIG_LIGHT = {"type": "point", "power": 400.0, "radius": 1.2,
             "to_world": [[1, 0, 0, 1.5], [0, 1, 0, -1.5], [0, 0, 1, 1.2], [0, 0, 0, 1]]}
K_SIGMA = 4.5      # per region and channel; 16 regions × 3 channels per comparison
# Rough interfaces: broad lobes, so that BSDF sampling and light sampling both find the light
# over much of the sphere (narrow lobes leave MIS little to weigh). Two slabs take the
# bidirectional pdf estimators, one slab next-event estimation through its exit.
TWO_SLABS = {"type": "layered",
             "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.3},
                            {"type": "dielectric", "ior": 1.3, "roughness": 0.2},
                            {"type": "conductor", "metal": "Cu", "roughness": 0.3}],
             "media": [{"sigma_t": 0.5, "albedo": 0.8, "phase": {"type": "hg", "g": 0.3}},
                       {"sigma_t": 0.5, "albedo": [0.5, 0.9, 0.5],
                        "phase": {"type": "microflake", "stddev": 0.3, "orientation": [1, 0, 0]}}]}
ONE_SLAB = {"type": "layered", "estimator": "bi",        # the walk (its table would have no pdf to defer)
            "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.3},
                           {"type": "conductor", "metal": "Au", "roughness": 0.2}],
            "media": [{"sigma_t": 1.0, "albedo": [0.9, 0.6, 0.4], "phase": {"type": "hg", "g": 0.5}}]}


# Transmissive with one rough interface: the lobes pdf of its transmissions is in closed form
# (with several rough interfaces, as STACKS["transmissive"], it is the approximate pdf).
ROUGH_COAT_OVER_GLASS = {"type": "layered",
                         "interfaces": [{"type": "dielectric", "ior": 1.4, "roughness": 0.35},
                                        {"type": "dielectric", "ior": 1.0, "roughness": 0.0}],
                         "media": [{"sigma_t": 0.4, "albedo": 0.9, "phase": {"type": "hg", "g": 0.6}}]}


def _scene(material, spp, pdf=None):
    return scene(16, 16, front_perspective(distance=4.0, half_width=0.3),
                 {"m": material}, {"ball": {"shape": "sphere", "radius": 1.0, "segments": 32}},
                 [{"mesh": "ball", "materials": ["m"]}], lights=[BIG_LIGHT],
                 world={"type": "constant", "color": [0.05] * 3, "strength": 1.0},
                 render={"spp": spp, "max_bounces": 3, "seed": 11, **({"layered": {"pdf": pdf}} if pdf else {})})


@pytest.mark.parametrize("material,pdf,deferred", [
    (TWO_SLABS, None, False), (TWO_SLABS, "approx", True), (TWO_SLABS, "stochastic", True),
    (ONE_SLAB, None, False), (ONE_SLAB, "approx", True), (STACKS["transmissive"], None, True),
    (ROUGH_COAT_OVER_GLASS, None, True)],
    ids=["two-slabs", "two-slabs-approx", "two-slabs-stochastic", "one-slab", "one-slab-approx",
         "transmissive", "transmissive-one-rough"])
def test_mis_with_deferred_and_immediate_pdfs_matches_bsdf_sampling_alone(material, pdf, deferred, monkeypatch):
    """``deferred``: an estimated pdf (approximate or stochastic; a transmissive stack's
    transmissions may take the approximate one) is deferred; the closed-form lobes pdf of a
    reflective stack is computed at the vertex (it costs about what deferring it saves)."""
    mis_deferred = render(_scene(material, 64, pdf))
    if deferred:
        assert mis_deferred.stats.get("layered_pdfs_deferred", 0) > 50       # the deferred path ran
    else:
        assert not mis_deferred.stats.get("layered_pdfs_deferred")
    with monkeypatch.context() as m:
        m.setattr(PointLight, "fills_sphere", True)      # as with a light-sampled environment
        mis_at_once = render(_scene(material, 64, pdf))
    assert not mis_at_once.stats.get("layered_pdfs_deferred")
    with monkeypatch.context() as m:
        m.setattr(PointLight, "light_sampled", False)    # no next-event estimation
        bsdf_only = render(_scene(material, 512, pdf))
    for a in (mis_deferred, mis_at_once):
        z = region_z(a, bsdf_only, 4)
        assert z.max() < K_SIGMA, z.max()
    # The two MIS renders differ (different random numbers for the pdfs) but agree as well.
    assert region_z(mis_deferred, mis_at_once, 4).max() < K_SIGMA
