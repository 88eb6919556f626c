"""A bound stack's scattering kernels sampled on direction grids, for the tabulated form of uniform
stacks (backend/layered/tabulated.py solves the stack by adding-doubling from these samples).

Everything here evaluates the walk's own per-lane code on the walk's own bound block ``B``
(table.py): the interfaces through ``iface.evaluate`` (importance transport: the flux that
arrives from wi and leaves towards wo, f·|cos θo|), the media's phase functions through
``phase.evaluate``. So the tables describe exactly the BSDF the walk estimates.

Directions are given as propagation azimuth differences: light travelling with azimuth φ_in
leaves with φ_out, Δφ = φ_out − φ_in (a mirror reflection and a straight refraction both have
Δφ = 0). ``mu_in``/``mu_out`` are |cos θ| of the nodes, ``s_in``: +1 when the light arrives from
above (travelling down), −1 from below; ``s_out``: +1 when it leaves upwards, −1 downwards.
"""
from __future__ import annotations

import math

from . import iface as ki
from . import phase as ph
from ..fresnel import dielectric as fresnel_dielectric
from ..jit import kernel

GOLDEN = 0.6180339887498949     # (√5 − 1)/2


@kernel(error_model="numpy")
def _between(nodes, x):
    """(k, t): x between nodes k and k + 1 with weight t of k + 1 (outside: the end node alone)."""
    n = nodes.shape[0]
    if x <= nodes[0]:
        return 0, 0.0
    if x >= nodes[n - 1]:
        return n - 2, 1.0
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if nodes[mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo, (x - nodes[lo]) / (nodes[lo + 1] - nodes[lo])


@kernel(error_model="numpy")
def _deposit(out, j, i, weight, cos_d, scale):
    """Add a sample's weight to the cosine coefficients out[j, i, :, c] of its cell."""
    M = out.shape[2]
    c = 1.0
    c_prev = cos_d
    for m in range(M):
        f = scale if m == 0 else 2.0 * scale
        out[j, i, m, 0] += f * weight[0] * c
        out[j, i, m, 1] += f * weight[1] * c
        out[j, i, m, 2] += f * weight[2] * c
        c_next = 2.0 * cos_d * c - c_prev
        c_prev = c
        c = c_next


@kernel(nogil=True, error_model="numpy")
def interface_projection(B, o, mu_in, j0, j1, s_in, weights, grid, refl, trans):
    """The cosine coefficients (over Δφ) of the interface's flux kernels from the nodes mu_in
    (light arriving from above, s_in = +1, or from below, −1) to the same nodes on each side:
    refl[j, i, m, c] (back to the arriving side) and trans[j, i, m, c]. Each sample's flux is
    shared between the two nodes around its |cos θ| linearly (the end nodes take all beyond
    them) and divided by ``weights[i]``, the integral of that share function (the "hat" of node
    i, which backend/layered/tabulated.py's quadrature weights are): the flux is kept and reads
    back as a local average of the density, however narrow the lobe.

    Projected through the interface's own sampler on a grid × grid of stratified numbers (its
    microfacet normals): each normal's reflection weighted by its Fresnel factor and its
    refraction by the rest, so the flux lands exactly where the interface sends it, however
    narrow the lobe (a point-sampled kernel would need nodes finer than a lobe). Rows j0 … j1 − 1
    only (threads share the rows)."""
    inv = 1.0 / grid
    norm = inv * inv / (2.0 * math.pi)
    for j in range(j0, j1):
        mi = mu_in[j]
        si = math.sqrt(max(1.0 - mi * mi, 0.0))
        wi = (-si, 0.0, s_in * mi)          # the light travels along −wi: azimuth 0
        kind = B[o + ki.IF_KIND]
        for q in range(grid * grid):
            # a Fibonacci lattice rather than a grid: at normal incidence a grid's second number
            # alone sets the normals' tilt, so its grid × grid points fell on `grid` rings of θ,
            # whose comb the node hats aliased (±4 % ripples); the lattice's are all distinct
            u0 = (q + 0.5) * inv * inv
            u1 = (0.5 + q * GOLDEN) % 1.0
            if kind == ki.DIELECTRIC:
                p = o + ki.IF_P
                au, av = B[p + 4], B[p + 5]
                m = ki._normal(int(B[o + ki.IF_DIST]), au, av, (wi[0] * s_in, wi[1] * s_in, wi[2] * s_in),
                               u0, u1)
                F = fresnel_dielectric(wi[0] * m[0] + wi[1] * m[1] + wi[2] * m[2], B[p])[0]
                branches = 2
            else:
                F = 1.0
                branches = 1
            for r in range(branches):
                u2 = 0.0 if r == 0 else 1.0
                share = F if r == 0 else 1.0 - F
                if not share > 0.0:
                    continue
                wo, w, _, _, _ = ki.sample(B, o, wi, u0, u1, u2, dens=False)
                if not (w[0] > 0.0 or w[1] > 0.0 or w[2] > 0.0):
                    continue
                mo = abs(wo[2])
                so = math.sqrt(max(1.0 - mo * mo, 0.0))
                cd = wo[0] / so if so > 1e-12 else 1.0
                same_side = wo[2] * wi[2] > 0.0
                target = refl if same_side else trans
                i, t = _between(mu_in, mo)
                v = (w[0] * share, w[1] * share, w[2] * share)
                cdc = min(max(cd, -1.0), 1.0)
                if t < 1.0:
                    _deposit(target, j, i, v, cdc, norm * (1.0 - t) / weights[i])
                if t > 0.0:
                    _deposit(target, j, i + 1, v, cdc, norm * t / weights[i + 1])


@kernel(nogil=True, error_model="numpy")
def phase_samples(B, o, FT, mu, phis, same, opposite):
    """The phase function at offset o between propagation directions: ``same[j, i, q]`` keeps
    the vertical direction (down → down), ``opposite[j, i, q]`` reverses it (down → up)."""
    for j in range(mu.shape[0]):
        mi = mu[j]
        si = math.sqrt(max(1.0 - mi * mi, 0.0))
        d_in = (si, 0.0, -mi)
        for i in range(mu.shape[0]):
            mo = mu[i]
            so = math.sqrt(max(1.0 - mo * mo, 0.0))
            for q in range(phis.shape[0]):
                c, s = math.cos(phis[q]), math.sin(phis[q])
                same[j, i, q] = ph.evaluate(B, o, FT, d_in, (so * c, so * s, -mo))
                opposite[j, i, q] = ph.evaluate(B, o, FT, d_in, (so * c, so * s, mo))


@kernel(nogil=True, error_model="numpy")
def delta_reflectance(B, o, mu, out):
    """out[i, c]: the reflectance of the smooth (delta) interface at offset o, light arriving
    from above at cos θ = mu[i] (the weight of its mirror sample, tint included)."""
    for i in range(mu.shape[0]):
        wi = (math.sqrt(max(1.0 - mu[i] * mu[i], 0.0)), 0.0, mu[i])
        _, w, _, _, _ = ki.sample(B, o, wi, 0.5, 0.5, 0.0, dens=False)
        out[i, 0], out[i, 1], out[i, 2] = w
