"""Array entry points of the per-lane phase functions (kernels/layered/phase.py) for the NumPy
phase classes (backend/layered/phase): parameter rows (1 = constant, or one per lane) and loops
over lanes calling the same per-lane code as the layered walk.

Random numbers: counter-based, lane i of a call with ``seed`` draws from the stream
``path_key(seed, i, 0)`` (the callers draw the seed from their NumPy generator)."""
from __future__ import annotations

from ..jit import kernel
from ..rng import path_key
from . import phase as ph


@kernel
def bind_rows(kind, a, v, choice, FT, P):
    """Rows of kind ``kind`` from the slots (phase.bind): ``a`` (1 | n,), ``v`` (1 | n, 3)."""
    for i in range(P.shape[0]):
        ia = i if a.shape[0] > 1 else 0
        iv = i if v.shape[0] > 1 else 0
        ph.bind(P[i], 0, kind, a[ia], (v[iv, 0], v[iv, 1], v[iv, 2]), choice, FT, -1)


@kernel
def bind_sggx_rows(s6, P):
    for i in range(P.shape[0]):
        ph.bind_sggx(P[i], 0, (s6[i, 0], s6[i, 1], s6[i, 2], s6[i, 3], s6[i, 4], s6[i, 5]))


@kernel
def _ri(P, i):
    return i if P.shape[0] > 1 else 0


@kernel
def eval_batch(P, FT, d_in, d_out, out):
    for i in range(d_in.shape[0]):
        out[i] = ph.evaluate(P[_ri(P, i)], 0, FT, (d_in[i, 0], d_in[i, 1], d_in[i, 2]),
                             (d_out[i, 0], d_out[i, 1], d_out[i, 2]))


@kernel
def scale_batch(P, FT, d, out):
    for i in range(d.shape[0]):
        out[i] = ph.sigma_scale(P[_ri(P, i)], 0, FT, (d[i, 0], d[i, 1], d[i, 2]))


@kernel
def sample_batch(P, FT, d_in, seed, max_candidates, R, d_out, weight, pdf, counts):
    """counts: [failed samples, largest number of candidates a lane drew]; R: uint64[2] scratch
    (the lane's stream state)."""
    for i in range(d_in.shape[0]):
        R[0] = path_key(seed, i, 0)
        R[1] = 0
        Pi = P[_ri(P, i)]
        di = (d_in[i, 0], d_in[i, 1], d_in[i, 2])
        s_in = ph.sigma_scale(Pi, 0, FT, di)
        d, w, p, _, _, k = ph.sample(Pi, 0, FT, di, s_in, R, max_candidates)
        d_out[i, 0], d_out[i, 1], d_out[i, 2] = d
        weight[i] = w
        pdf[i] = p
        if w == 0.0:
            counts[0] += 1
        counts[1] = max(counts[1], k)
