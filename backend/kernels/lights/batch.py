"""Array entry points of the per-lane light code, for NumPy callers (the Light classes' methods,
the light selector, tests, load-time power estimates): loops over lanes calling the same
functions the integrator kernels call (dispatch.py). Light indices ``li`` are (1,) arrays (one
light for every lane) or (n,) arrays (one per lane); points and directions (n, 3) float64.

The lane loops are compiled without reference counting (``_nrt=False``, as every ``@kernel``):
they allocate nothing, and every access to a light-table array inside a lane (the inlined dispatch
reads ``lt.params`` etc. per call) would otherwise cost an atomic increment and a decrement call
that LLVM cannot prune across the non-inlined kind functions — measured 145 → 40 ns per
point-light sample (1M lanes). An integrator kernel that calls dispatch.py per lane should do the
same, or read the table's arrays into locals once, outside its lane loop.
"""
from __future__ import annotations

from . import dispatch as _dispatch
from . import ies as _ies
from . import point as _point
from . import profiles as _prof
from . import selection as _sel
from ..jit import kernel
from ..lanes import at, row3, set_row3
from .spot import attenuation


@kernel(nogil=True)
def sample(lt, tx, li, p, u, wi, dist, value, pdf, delta):
    for i in range(p.shape[0]):
        w, t, val, pd, dl = _dispatch.sample(lt, tx, at(li, i), row3(p, i), u[i, 0], u[i, 1])
        set_row3(wi, i, w)
        dist[i] = t
        set_row3(value, i, val)
        pdf[i] = pd
        delta[i] = dl


@kernel(nogil=True)
def intersect(lt, li, o, d, tmax, out):
    for i in range(o.shape[0]):
        out[i] = _dispatch.intersect(lt, at(li, i), row3(o, i), row3(d, i), tmax[i])


@kernel(nogil=True)
def eval_hit(lt, li, o, d, t, out):
    for i in range(o.shape[0]):
        set_row3(out, i, _dispatch.eval_hit(lt, at(li, i), row3(o, i), row3(d, i), t[i]))


@kernel(nogil=True)
def pdf_hit(lt, li, o, d, t, out):
    for i in range(o.shape[0]):
        out[i] = _dispatch.pdf_hit(lt, at(li, i), row3(o, i), row3(d, i), t[i])


@kernel(nogil=True)
def eval_escaped(lt, li, d, out):
    for i in range(d.shape[0]):
        set_row3(out, i, _dispatch.eval_escaped(lt, at(li, i), row3(d, i)))


@kernel(nogil=True)
def pdf_escaped(lt, li, d, out):
    for i in range(d.shape[0]):
        out[i] = _dispatch.pdf_escaped(lt, at(li, i), row3(d, i))


@kernel(nogil=True)
def mesh_pdf_hit(lt, li, o, d, t, tri, out):
    for i in range(o.shape[0]):
        out[i] = _dispatch.mesh_pdf_hit(lt, at(li, i), row3(o, i), row3(d, i), t[i], tri[i])


@kernel(nogil=True)
def mesh_eval(lt, li, d, tri, out):
    for i in range(d.shape[0]):
        set_row3(out, i, _dispatch.mesh_eval(lt, at(li, i), row3(d, i), tri[i]))


@kernel(nogil=True)
def select(lt, p, u, li, prob):
    for i in range(p.shape[0]):
        li[i], prob[i] = _dispatch.select(lt, row3(p, i), u[i])


@kernel(nogil=True)
def select_prob(lt, p, li, out):
    for i in range(p.shape[0]):
        out[i] = _dispatch.select_prob(lt, row3(p, i), at(li, i))


@kernel(nogil=True)
def received_power(lt, j, p, out):
    for i in range(p.shape[0]):
        out[i] = _sel.received_power(lt, j, row3(p, i))


@kernel(nogil=True)
def directional_factor(lt, li, w, out):
    """Spot/IES factor of a point light on emission along world directions w."""
    for i in range(w.shape[0]):
        out[i] = _point.directional_factor(lt.params, lt.iparams, li, lt.aux, row3(w, i))


@kernel(nogil=True)
def spot_attenuation(cos_axis, cos_half, smooth, out):
    for i in range(cos_axis.shape[0]):
        out[i] = attenuation(cos_axis[i], cos_half, smooth)


@kernel(nogil=True)
def ies_intensity_angles(block, nh, nv, flags, h, v, out):
    for i in range(h.shape[0]):
        out[i] = _ies.intensity_angles(block, 0, nh, nv, flags, h[i], v[i])


@kernel(nogil=True)
def ies_intensity(block, nh, nv, flags, d, out):
    for i in range(d.shape[0]):
        out[i] = _ies.intensity(block, 0, nh, nv, flags, row3(d, i))


@kernel(nogil=True)
def ies_directions_to_angles(d, h, v):
    for i in range(d.shape[0]):
        h[i], v[i] = _ies.directions_to_angles(row3(d, i))


@kernel(nogil=True)
def profile_eval(kind, tan_max, cutoff, beam, cos_theta, out):
    for i in range(cos_theta.shape[0]):
        out[i] = _prof.evaluate(kind, tan_max, cutoff, beam, cos_theta[i])


@kernel(nogil=True)
def cone_sample(block, bins, mu_lo, width, u, mu, phi, pdf):
    for i in range(u.shape[0]):
        mu[i], phi[i], pdf[i] = _prof.cone_sample(block, 0, bins, mu_lo, width, u[i, 0], u[i, 1])


@kernel(nogil=True)
def cone_pdf(block, bins, mu_lo, width, mu, out):
    for i in range(mu.shape[0]):
        out[i] = _prof.cone_pdf(block, 0, bins, mu_lo, width, mu[i])
