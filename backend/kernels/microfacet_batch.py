"""Array entry points of ``microfacet.py`` for NumPy callers (tests, the BSDF inspector):
loops over lanes calling the per-lane functions. αu/αv are (1,) or (n,) arrays."""
from __future__ import annotations

from numba import njit

from . import microfacet as mf


@njit(cache=True, _nrt=False)
def _a(a, i):
    return a[i if a.shape[0] > 1 else 0]


@njit(cache=True, _nrt=False)
def _v(a, i):
    return (a[i, 0], a[i, 1], a[i, 2])


@njit(cache=True, _nrt=False)
def D(dist, au, av, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.D(dist, _a(au, i), _a(av, i), _v(m, i))


@njit(cache=True, _nrt=False)
def smith_lambda(dist, au, av, w, out):
    for i in range(out.shape[0]):
        out[i] = mf.smith_lambda(dist, _a(au, i), _a(av, i), _v(w, i))


@njit(cache=True, _nrt=False)
def G1(dist, au, av, w, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.G1(dist, _a(au, i), _a(av, i), _v(w, i), _v(m, i))


@njit(cache=True, _nrt=False)
def G(dist, masking, au, av, wi, wo, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.G(dist, masking, _a(au, i), _a(av, i), _v(wi, i), _v(wo, i), _v(m, i))


@njit(cache=True, _nrt=False)
def sample_ndf(dist, au, av, u, out):
    for i in range(out.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = mf.sample_ndf(dist, _a(au, i), _a(av, i), u[i, 0], u[i, 1])


@njit(cache=True, _nrt=False)
def pdf_ndf(dist, au, av, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.pdf_ndf(dist, _a(au, i), _a(av, i), _v(m, i))


@njit(cache=True, _nrt=False)
def sample_visible(dist, au, av, wi, u, out):
    for i in range(out.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = mf.sample_visible(dist, _a(au, i), _a(av, i), _v(wi, i),
                                                            u[i, 0], u[i, 1])


@njit(cache=True, _nrt=False)
def pdf_visible(dist, au, av, wi, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.pdf_visible(dist, _a(au, i), _a(av, i), _v(wi, i), _v(m, i))


@njit(cache=True, _nrt=False)
def G1_separable(dist, au, av, w, m, out):
    for i in range(out.shape[0]):
        out[i] = mf.G1_separable(dist, _a(au, i), _a(av, i), _v(w, i), _v(m, i))
