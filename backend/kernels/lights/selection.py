"""Light selection per lane: which light next-event estimation samples, and with what probability.

Two modes (scene ``render.light_selection``; the table's ``local_selection``):

* global ("power"): probability ∝ each light's power everywhere (``sel_dist`` over the lights of
  positive power, ``sel_pmf`` per light);
* local (default): probability ∝ the light's power *as received at the shading point*: the power
  spread over the sphere at the point's distance, i.e. an unoccluded irradiance scale in W/m²
  (``received_power``). Distant lights (sun, world) have no distance: their power is defined over
  the scene's bounding disk (P = E·πR²), so their received scale is P/(πR²) = E. A light very
  close to a point is capped at its own size (no division by ~0). One-sided area lights give 0
  behind themselves, where they cannot contribute. This matters as soon as lights differ in
  distance: with a global table a 40 m sunlit floor made a nearby 400 W area light get 6 % of the
  samples and the render noise 4× higher than with local selection (measured on the demo scene).
  Where no light reaches a point the global table is used (the contributions are 0 anyway).

Lights whose power is zero are never picked and have probability 0 for MIS. Probabilities are
exact (they are what MIS uses). Cost: a loop over the lights per lane (two for ``select``):
~10 ns per light and pass.
"""
from __future__ import annotations

import math

from .. import discrete as _d
from ..jit import inlined, kernel
from ..vec import dot
from . import area as _ka
from . import profiles as _prof
from .common import (C_POWER, C_SEL_AREA, C_SEL_INTENSITY, C_SEL_NORMAL, C_SEL_PEAK, C_SEL_POS, C_SEL_SIZE2,
                     I_SEL, SEL_ONE_SIDED, SEL_ONE_SIDED_PROFILE, SEL_PROFILE, SEL_UNIFORM)
from .point import directional_factor

from ..consts import INV_PI


@inlined
def received_power_row(P, I, aux, j, how, radius, p):
    """Power of light j (parameter matrices P, I, selection kind ``how``) as received at point
    p (W/m² scale; see the module docstring); ``radius`` = the scene radius R [m]."""
    power = P[j, C_POWER]
    if not power > 0.0:
        return 0.0
    if how == SEL_UNIFORM:
        return power * INV_PI / (radius * radius)
    rel = (p[0] - P[j, C_SEL_POS], p[1] - P[j, C_SEL_POS + 1], p[2] - P[j, C_SEL_POS + 2])
    d2 = dot(rel, rel)
    if how == SEL_ONE_SIDED or how == SEL_ONE_SIDED_PROFILE:
        h = rel[0] * P[j, C_SEL_NORMAL] + rel[1] * P[j, C_SEL_NORMAL + 1] + rel[2] * P[j, C_SEL_NORMAL + 2]
        if not h > 0.0:
            return 0.0
        cos_e = min(max(h / math.sqrt(max(d2, 1e-300)), 0.0), 1.0)
        g = cos_e
        if how == SEL_ONE_SIDED_PROFILE:
            # The profile's radiance towards p over a Lambertian emitter's of the same power
            # (f(θ)/K: up to 1/K ≈ 11× on the axis of a 60° spread, 0 outside it). The floor
            # below keeps a share for points that only an edge of the emitter reaches.
            g = cos_e * P[j, C_SEL_PEAK] * _prof.evaluate(I[j, _ka.I_PROFILE], P[j, _ka.A_SPREAD_TAN],
                                                          P[j, _ka.A_CUTOFF], P[j, _ka.A_BEAM], cos_e)
        # Near the emitter the received scale saturates at its own area (no 1/d² blow-up).
        return power * max(g, 0.05) * INV_PI / max(d2, P[j, C_SEL_AREA])
    if how == SEL_PROFILE:
        # Intensity towards p (spot cone × IES table): zero where the profile is zero, so no
        # sample is spent on a light that cannot reach p.
        n = math.sqrt(d2)
        w = (rel[0] / n, rel[1] / n, rel[2] / n) if n > 0.0 else (0.0, 0.0, -1.0)
        return P[j, C_SEL_INTENSITY] * directional_factor(P, I, j, aux, w) / max(d2, P[j, C_SEL_SIZE2])
    return power * 0.25 * INV_PI / max(d2, P[j, C_SEL_SIZE2])


@inlined
def received_power(lt, j, p):
    """Power of light j as received at point p (W/m² scale)."""
    return received_power_row(lt.params, lt.iparams, lt.aux, j, lt.iparams[j, I_SEL], lt.sel_radius, p)


@kernel
def _total(params, iparams, aux, active, radius, p):
    total = 0.0
    for k in range(active.shape[0]):
        j = active[k]
        total += received_power_row(params, iparams, aux, j, iparams[j, I_SEL], radius, p)
    return total


@kernel
def _select_local(params, iparams, aux, active, radius, p, u):
    total = _total(params, iparams, aux, active, radius, p)
    by_power = not total > 0.0
    if by_power:
        # nothing reaches p: the global table (the contributions are 0 anyway)
        total = 0.0
        for k in range(active.shape[0]):
            total += params[active[k], C_POWER]
    c = 0.0
    for k in range(active.shape[0]):
        j = active[k]
        w = params[j, C_POWER] if by_power else received_power_row(params, iparams, aux, j, iparams[j, I_SEL], radius, p)
        c += w
        if u < c / total:           # a bin of zero width is never the first with u < cdf
            return j, w / total
    # u at the very top (rounding of the cdf): the last bin of positive weight
    for k in range(active.shape[0] - 1, -1, -1):
        j = active[k]
        w = params[j, C_POWER] if by_power else received_power_row(params, iparams, aux, j, iparams[j, I_SEL], radius, p)
        if w > 0.0:
            return j, w / total
    return -1, 0.0


@inlined
def select(lt, p, u):
    """(light index, its probability) for a uniform u in [0, 1); (−1, 0) if nothing emits."""
    na = lt.sel_active.shape[0]
    if na == 0:
        return -1, 0.0
    if na == 1:
        return lt.sel_active[0], 1.0          # one light: no table lookup
    if lt.local_selection == 0:
        k, prob, _ = _d.sample_1d(lt.sel_dist, 0, na, u)
        return lt.sel_active[k], prob
    return _select_local(lt.params, lt.iparams, lt.aux, lt.sel_active, lt.sel_radius, p, u)


@inlined
def select_prob(lt, p, li):
    """Probability that ``select`` at point p returns light li (for MIS of light hits)."""
    if li < 0 or not lt.params[li, C_POWER] > 0.0:
        return 0.0
    if lt.local_selection == 0:
        return lt.sel_pmf[li]
    total = _total(lt.params, lt.iparams, lt.aux, lt.sel_active, lt.sel_radius, p)
    if total > 0.0:
        return received_power(lt, li, p) / total
    return lt.sel_pmf[li]
