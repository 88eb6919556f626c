"""The compiled connections (backend/kernels/layered/estimators.py) against the straightforward
NumPy pair-list implementation (tests/layered_bidir_reference.py): on the same walks both must
give the same per-lane sums — values, approximate and stochastic pdfs — up to rounding.

This is an implementation cross-check (two independent codings of the same estimator); the
estimator itself is validated statistically in test_layered_estimators.py / _physics.py."""
import copy

import numpy as np
import pytest

import layered_bidir_reference as reference
from backend.layered.probe import connect, walks
from layered_util import FIG2_TOP, LOSSLESS_SAMPLER, REFERENCE, TRANSMISSIVE, bind, load

ABSORBING = {"type": "layered",
             "interfaces": [{"type": "dielectric", "ior": 1.4, "roughness": 0.1},
                            {"type": "dielectric", "ior": 1.3, "roughness": 0.2, "distribution": "beckmann",
                             "masking": "separable"},
                            {"type": "diffuse", "color": 0.7}],
             "media": [{"sigma_t": [0.3, 0.6, 1.2], "albedo": 0.0},
                       {"sigma_t": 0.7, "albedo": [0.8, 0.9, 0.6], "phase": {"type": "vmf", "kappa": 5.0}}]}
EMPTY_SGGX = {"type": "layered",
              "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.0},
                             {"type": "null"},
                             {"type": "conductor", "metal": "Au", "roughness": 0.2}],
              "media": [{"sigma_t": 0.0},
                        {"sigma_t": 1.0, "albedo": 0.9,
                         "phase": {"type": "sggx", "shape": "flake", "roughness": 0.4,
                                   "orientation": [0.2, 0.1, 1.0]}}]}
NORMALS = copy.deepcopy(FIG2_TOP)
NORMALS["interfaces"][0]["normal"] = [0.2, -0.1, 0.97]
NORMALS["interfaces"][1]["normal"] = [-0.15, 0.05, 0.98]

CASES = {"reference": REFERENCE, "fig2-top": FIG2_TOP, "transmissive": TRANSMISSIVE,
         "lossless": LOSSLESS_SAMPLER, "absorbing": ABSORBING, "empty-sggx": EMPTY_SGGX,
         "normals": NORMALS}
# (A nested stack is left out: its interface is itself stochastic, so the two codings, which
# draw random numbers in different orders, give different — equally valid — estimates.)


def _directions(rng, n, transmissive):
    u = rng.random((2, n))
    r, phi = np.sqrt(u[0]), 2 * np.pi * u[1]
    d = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u[0])])
    if transmissive:
        d[2] *= np.where(rng.random(n) < 0.4, -1.0, 1.0)
    return d


@pytest.mark.parametrize("name", list(CASES))
def test_blocked_connections_equal_pair_list(name):
    n = 1500
    mat = load(CASES[name])
    bsdf = bind(mat, n)
    stack = reference.StackView(bsdf)
    rng = np.random.default_rng(5)
    wi = _directions(rng, n, mat.transmissive)
    wo = _directions(rng, n, mat.transmissive)
    L, R = walks(bsdf, wi.T, rng), walks(bsdf, wo.T, rng)
    ref = reference.bidirectional(stack, wo, L, R, rng)
    new = connect(bsdf, wo.T, L, R)
    scale = np.maximum(np.abs(ref).max(axis=0), 1e-300)
    assert np.abs(ref).max() > 0
    assert np.all(np.abs(new - ref) <= 1e-9 * scale)
    for approx in (True, False):
        slabs = stack.N - 1
        cap = 2 * slabs if approx else 1024
        # The stochastic pdf's two walks share a hero channel (walk.walk); the approximate
        # pdf's walks have none.
        Lw = walks(bsdf, wi.T, rng, approx=approx, cap=cap, purpose="pdf")
        hero = Lw.hero if np.any(Lw.hero >= 0) else None
        if name == "transmissive":
            assert (hero is not None) == (not approx)  # the chromatic case is exercised
        Lp = Lw
        Rp = walks(bsdf, wo.T, rng, approx=approx, cap=cap, purpose="pdf", hero=hero)
        nmax = np.where(wi[2] * wo[2] > 0, 2 * slabs + 1, slabs + 1) if approx else None
        p_ref = reference.bidirectional(stack, wo, Lp, Rp, rng, pdf_mode=True, approx=approx, nmax=nmax,
                                        hero=hero)
        p_new = connect(bsdf, wo.T, Lp, Rp, pdf_mode=True, approx=approx, nmax=nmax, hero=hero)
        assert np.all(np.isfinite(p_new))
        assert np.all(np.abs(p_new - p_ref) <= 1e-9 * np.maximum(np.abs(p_ref), 1e-300)), approx
