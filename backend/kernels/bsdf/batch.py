"""Array entry points of the per-lane BSDFs, for NumPy callers (the BSDF inspector, tests, the
layered stacks' interfaces): loops over lanes calling the same per-lane code the integrator uses.

Per-lane parameters are arrays whose first dimension is 1 (a constant, broadcast to every lane)
or n (one value per lane): RGB (1|n, 3), scalars (1|n,), smooth flags (1|n,) bool.
"""
from __future__ import annotations

from . import conductor, dielectric, diffuse
from .. import materials as km
from ..jit import kernel
from ..lanes import at, rgb_at, row3


@kernel
def _put_eval(i, result, f, pdf):
    """Lane i's (value, pdf) into the output arrays."""
    f[i, 0], f[i, 1], f[i, 2] = result[0]
    pdf[i] = result[1]


@kernel
def _put_sample(i, result, wo, weight, pdf, delta):
    """Lane i's (direction, weight, pdf, is_delta) into the output arrays."""
    wo[i, 0], wo[i, 1], wo[i, 2] = result[0]
    weight[i, 0], weight[i, 1], weight[i, 2] = result[1]
    pdf[i] = result[2]
    delta[i] = result[3]


@kernel
def diffuse_eval_pdf(color, wi, wo, f, pdf):
    for i in range(wi.shape[0]):
        res = diffuse.eval_pdf(rgb_at(color, i), row3(wi, i), row3(wo, i))
        _put_eval(i, res, f, pdf)


@kernel
def diffuse_sample(color, wi, u, wo, weight, pdf, delta):
    for i in range(wi.shape[0]):
        res = diffuse.sample(rgb_at(color, i), row3(wi, i), u[i, 0], u[i, 1])
        _put_sample(i, res, wo, weight, pdf, delta)


@kernel
def conductor_eval_pdf(eta, k, tint, au, av, smooth, dist, masking, wi, wo, f, pdf):
    for i in range(wi.shape[0]):
        res = conductor.eval_pdf(rgb_at(eta, i), rgb_at(k, i), rgb_at(tint, i), at(au, i), at(av, i),
                                 at(smooth, i), dist, masking, row3(wi, i), row3(wo, i))
        _put_eval(i, res, f, pdf)


@kernel
def conductor_sample(eta, k, tint, au, av, smooth, dist, masking, wi, u, wo, weight, pdf, delta):
    for i in range(wi.shape[0]):
        res = conductor.sample(rgb_at(eta, i), rgb_at(k, i), rgb_at(tint, i), at(au, i), at(av, i),
                               at(smooth, i), dist, masking, row3(wi, i), u[i, 0], u[i, 1])
        _put_sample(i, res, wo, weight, pdf, delta)


@kernel
def conductor_albedo(eta, k, tint, out):
    for i in range(out.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = conductor.albedo(rgb_at(eta, i), rgb_at(k, i), rgb_at(tint, i))


@kernel
def dielectric_eval_pdf(eta, tint, au, av, smooth, dist, masking, mode, wi, wo, f, pdf):
    for i in range(wi.shape[0]):
        res = dielectric.eval_pdf(at(eta, i), rgb_at(tint, i), at(au, i), at(av, i), at(smooth, i),
                                  dist, masking, mode, row3(wi, i), row3(wo, i))
        _put_eval(i, res, f, pdf)


@kernel
def dielectric_sample(eta, tint, au, av, smooth, dist, masking, mode, wi, u, wo, weight, pdf, delta):
    for i in range(wi.shape[0]):
        res = dielectric.sample(at(eta, i), rgb_at(tint, i), at(au, i), at(av, i), at(smooth, i),
                                dist, masking, mode, row3(wi, i), u[i, 0], u[i, 1], u[i, 2])
        _put_sample(i, res, wo, weight, pdf, delta)


# ----------------------------------------------------------------------------- any material row
# One row of a material table (kernels/materials.py), bound per lane at its (u, v): the BSDFs
# whose parameters travel as a row, such as the deterministic layered forms.
@kernel
def _uv(uv, i):
    j = i if uv.shape[0] > 1 else 0
    return uv[j, 0], uv[j, 1]


@kernel
def row_eval_pdf(MT, TX, m, uv, mode, wi, wo, f, pdf):
    for i in range(wi.shape[0]):
        u, v = _uv(uv, i)
        p = km.bind(MT, TX, m, u, v)
        res = km.eval_pdf(MT.tables, MT.kind[m], MT.dist[m], MT.masking[m], p, mode, row3(wi, i), row3(wo, i))
        _put_eval(i, res, f, pdf)


@kernel
def row_sample(MT, TX, m, uv, mode, wi, u, wo, weight, pdf, delta):
    for i in range(wi.shape[0]):
        a, b = _uv(uv, i)
        p = km.bind(MT, TX, m, a, b)
        res = km.sample(MT.tables, MT.kind[m], MT.dist[m], MT.masking[m], p, mode, row3(wi, i),
                        u[i, 0], u[i, 1], u[i, 2])
        _put_sample(i, res, wo, weight, pdf, delta)


@kernel
def row_albedo(MT, TX, m, uv, wi, out):
    for i in range(wi.shape[0]):
        u, v = _uv(uv, i)
        p = km.bind(MT, TX, m, u, v)
        out[i, 0], out[i, 1], out[i, 2] = km.albedo(MT.tables, MT.kind[m], p, row3(wi, i))
