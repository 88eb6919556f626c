"""NumPy ufuncs over the per-lane special functions and Fresnel terms (broadcasting like any
ufunc), for NumPy callers: ``backend/materials/fresnel.py``, ``specfun.py`` and the layered
walks. The maths is the per-lane code in ``fresnel.py`` / ``specfun.py``: one implementation."""
from __future__ import annotations

from . import cache as _cache

_cache.configure()                  # before the first decorator: the keyed cache folder (kernels/cache.py)

from numba import guvectorize, vectorize  # noqa: E402
from numba.core.registry import cpu_target  # noqa: E402

from . import fresnel, specfun  # noqa: E402

# Building a ufunc's wrapper lowers code in the CPU target context even when its kernel comes from
# the cache, and the lean cache loader (cache._lean_cache_loads) leaves that context unrefreshed:
# importing this module first in a process, with the ufuncs cached, failed with
# NumbaNotImplementedError (get_constant of intp), e.g. collecting tests/test_bsdf_cli.py in a
# second test run. Refreshing here costs what the lean loader saves, only where ufuncs are used.
cpu_target.target_context.refresh()


@vectorize(["float64(float64)"], cache=True)
def erfc(x):
    return specfun.erfc(x)


@vectorize(["float64(float64)"], cache=True)
def erfinv_from_uniform(u):
    return specfun.erfinv_from_uniform(u)


@vectorize(["float64(float64, float64, float64)"], cache=True)
def conductor(cos_i, eta, k):
    return fresnel.conductor(cos_i, eta, k)


@guvectorize(["void(float64, float64, float64, float64[:], float64[:])"], "(),(),()->(),()",
             cache=True)
def conductor_polarized(cos_i, eta, k, rs, rp):
    rs[0], rp[0] = fresnel.conductor_polarized(cos_i, eta, k)


@guvectorize(["void(float64, float64, float64[:], float64[:], float64[:], float64[:])"],
             "(),()->(),(),(),()", cache=True)
def dielectric_polarized(cos_i, eta, rs, rp, cos_t, eta_ti):
    rs[0], rp[0], cos_t[0], eta_ti[0] = fresnel.dielectric_polarized(cos_i, eta)


@guvectorize(["void(float64, float64, float64[:], float64[:], float64[:])"],
             "(),()->(),(),()", cache=True)
def dielectric(cos_i, eta, F, cos_t, eta_ti):
    F[0], cos_t[0], eta_ti[0] = fresnel.dielectric(cos_i, eta)
