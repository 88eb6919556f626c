"""Array entry points of ``microfacet.py`` for NumPy callers (tests, the BSDF inspector):
loops over lanes calling the per-lane functions. αu/αv are (1,) or (n,) arrays."""
from __future__ import annotations

from . import microfacet as mf
from .jit import kernel
from .lanes import at, row3


D_OF, LAMBDA_OF, PDF_NDF_OF = 0, 1, 2     # the queries of one direction (``of_direction``)


@kernel
def of_direction(query, dist, au, av, w, out):
    """Per lane, D(w), Λ(w) or the density of ``sample_ndf`` at w, as ``query`` says."""
    for i in range(out.shape[0]):
        a, b, v = at(au, i), at(av, i), row3(w, i)
        if query == D_OF:
            out[i] = mf.D(dist, a, b, v)
        elif query == LAMBDA_OF:
            out[i] = mf.smith_lambda(dist, a, b, v)
        else:
            out[i] = mf.pdf_ndf(dist, a, b, v)


@kernel
def G1(dist, au, av, w, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.G1(dist, at(au, i), at(av, i), row3(w, i), row3(m, i))


@kernel
def G(dist, masking, au, av, wi, wo, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.G(dist, masking, at(au, i), at(av, i), row3(wi, i), row3(wo, i), row3(m, i))


@kernel
def sample_ndf(dist, au, av, u, out):
    for i in range(out.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = mf.sample_ndf(dist, at(au, i), at(av, i), u[i, 0], u[i, 1])


@kernel
def sample_visible(dist, au, av, wi, u, out):
    for i in range(out.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = mf.sample_visible(dist, at(au, i), at(av, i), row3(wi, i),
                                                            u[i, 0], u[i, 1])


@kernel
def pdf_visible(dist, au, av, wi, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.pdf_visible(dist, at(au, i), at(av, i), row3(wi, i), row3(m, i))


@kernel
def G1_separable(dist, au, av, w, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.G1_separable(dist, at(au, i), at(av, i), row3(w, i), row3(m, i))
