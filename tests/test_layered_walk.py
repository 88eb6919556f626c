"""The walk's recorded MIS coefficients (backend/kernels/layered/walk.py) against a recomputation from
scratch: for every recorded vertex the forward/reverse direction densities are re-evaluated with
the interface kernels and phase functions, the depth densities of both edge directions with the
slab operators, and the paper's unfolded recurrences (running sums P and products Q, appendix B
of Guo et al. 2018) are run over each lane's path. The walk folds all of this into a few running
coefficients and caches extinction scales, so this checks that bookkeeping independently."""
import numpy as np
import pytest

from backend.kernels.layered.walk import BIG
from backend.layered.probe import eval_at, slab_depth_density, walks
from layered_util import FIG2_TOP, REFERENCE, TRANSMISSIVE, bind, load

ABSORBING = {"type": "layered",
             "interfaces": [{"type": "dielectric", "ior": 1.4, "roughness": 0.1},
                            {"type": "dielectric", "ior": 1.3, "roughness": 0.2, "distribution": "beckmann"},
                            {"type": "diffuse", "color": 0.7}],
             "media": [{"sigma_t": [0.3, 0.6, 1.2], "albedo": 0.0},
                       {"sigma_t": 0.7, "albedo": [0.8, 0.9, 0.6], "phase": {"type": "vmf", "kappa": 5.0}}]}
CASES = {"reference": REFERENCE, "fig2-top": FIG2_TOP, "transmissive": TRANSMISSIVE, "absorbing": ABSORBING}


def _inv(x):
    return np.where(x > 0, 1.0 / np.where(x > 0, x, 1.0), 0.0)


def _depth_density(bsdf, slab, lanes, d, t0, t1, to_medium, hero=None):
    """Density of producing depth t1 from t0 along d in ``slab`` (1 where no free flight is
    sampled: empty or absorbing slabs). ``hero`` (per lane): the channel whose single-channel
    density a stochastic-pdf walk records in chromatic media (channel mean if None)."""
    out = np.ones(d.shape[1])
    for k in range(int(slab.max()) + 1 if slab.size else 0):
        pos = np.flatnonzero(slab == k)
        if not pos.size:
            continue
        out[pos] = slab_depth_density(bsdf, k, np.take(d, pos, axis=1).T, t0[pos], t1[pos], to_medium[pos],
                                      None if hero is None else hero[lanes[pos]])
    return out


@pytest.mark.parametrize("purpose", ["value", "pdf"])
@pytest.mark.parametrize("name", list(CASES))
def test_recorded_mis_coefficients_match_recomputation(name, purpose):
    n = 1500
    mat = load(CASES[name])
    stack = bind(mat, n)
    rng = np.random.default_rng(21)
    u = rng.random((2, n))
    w0 = np.stack([np.sqrt(u[0]) * np.cos(6.283 * u[1]), np.sqrt(u[0]) * np.sin(6.283 * u[1]),
                   np.sqrt(1 - u[0])])
    if mat.transmissive:
        w0[2] *= np.where(rng.random(n) < 0.3, -1.0, 1.0)
    rec = res = walks(stack, w0.T, rng, purpose=purpose)
    # A pdf walk records its hero channel's depth densities (walk.walk); a value walk the means.
    hero = res.hero if purpose == "pdf" and np.any(res.hero >= 0) else None
    if name == "transmissive":
        assert (hero is not None) == (purpose == "pdf")  # the chromatic case is exercised
    p = rec.perm  # lane-major, walk order within a lane
    lane, k, kind, layer, t = rec.lane[p], rec.k[p], rec.kind[p], rec.layer[p], rec.t[p]
    w_in, w_out, delta = rec.w_in[:, p], rec.w_out[:, p], rec.delta[p]
    # Direction densities from scratch.
    _, pf, pr = eval_at(stack, kind, layer, lane, w_in, w_out)
    pf = np.where(delta, 1.0, pf)
    pr = np.where(delta, 1.0, pr)
    # Failed samples (weight 0, the walk ends there) record density 0.
    live = rec.pdf_fwd[p] > 0
    assert np.allclose(pf[live], rec.pdf_fwd[p][live], rtol=1e-9, atol=0)
    pf = np.where(live, pf, 0.0)
    # Depth densities of the edge into each vertex (from the previous one) and back.
    prev = np.arange(p.size) - 1
    first = k == 1
    prev[first] = 0
    slab_e = np.where(kind == 1, np.where(w_in[2] > 0, layer - 1, layer), layer)  # slab of the edge
    d_e = -w_in
    dens_fwd = np.where(first, 1.0, _depth_density(stack, slab_e, lane, d_e, t[prev], t, kind == 0, hero))
    dens_rev = np.where(first, 1.0, _depth_density(stack, slab_e, lane, -d_e, t, t[prev], kind[prev] == 0,
                                                   hero))
    # The paper's recurrences, vertex by vertex along each lane.
    P = np.zeros(p.size)
    Q = np.zeros(p.size)
    for i in range(2, int(k.max()) + 1):
        at = np.flatnonzero(k == i)
        b = at - 1  # previous vertex (same lane, lane-major order)
        if i == 2:
            Q[at] = pr[b] * dens_rev[at]
            continue
        c = at - 2
        r_z = dens_rev[at] * _inv(dens_fwd[b])
        r_d = pr[b] * _inv(pf[c])
        P[at] = r_z * ((~delta[b]) + r_d * ((~delta[c]) + P[b]))
        Q[at] = r_z * r_d * Q[b]
    pf_prev = np.where(first, 1.0, pf[prev])
    dl_prev = np.where(first, False, delta[prev])
    inv_dens = np.where(first, 0.0, _inv(dens_fwd))
    a = ((~dl_prev) + P) * _inv(pf_prev)
    own = (~delta) * 1.0
    b1 = inv_dens * (own + pr * a)
    close = lambda x, y: np.allclose(x, y, rtol=1e-8, atol=1e-280)  # noqa: E731
    assert close(rec.c1[p], np.minimum(inv_dens, BIG))
    assert close(rec.c2[p], np.minimum(inv_dens * a, BIG))
    assert close(rec.A[p], np.minimum(_inv(pf) * own, BIG))
    assert close(rec.B[p], np.minimum(_inv(pf) * b1, BIG))
    if purpose == "pdf":
        qb = np.where(first, 1.0, inv_dens * Q * _inv(pf_prev))
        g = rec.gamma[p]
        assert close(rec.qbg[p], qb * g)
        assert close(rec.rev[p], _inv(pf) * pr * qb * g)
    else:
        # Throughputs: thru1 = thru0 · (sampled weight); consecutive vertices chain up to the
        # roulette factor (≥ 1) and the slab factor in between.
        assert np.all(rec.thru0 >= 0) and np.all(np.isfinite(rec.thru1))
