"""A dielectric interface over a Lambertian body, in closed form: the two-layer stacks of every
non-metallic Principled BSDF, evaluated without the random walk's noise.

The stack (backend/layered/coated_diffuse.py decides which stacks qualify): a smooth or rough isotropic
dielectric of relative index η with a constant transmission tint t, an empty or purely absorbing
slab of optical depth τ (RGB), and a Lambertian body of albedo ρ (a texture may vary it, and the
interface's roughness). Light either reflects at the interface (its own BSDF, exactly as the
walk's interface) or enters. The body re-emits uniformly whatever reaches it, so only the *flux*
that reaches it matters, not its directions, and the light that enters sums to a closed form:

  E(μ)   = ∫ f_t(wi → w) |cos θ| e^(−τ/|cos θ|) dw      (wi at cos θi = μ; importance transport:
           the fraction of the flux arriving from wi that reaches the body; tint t included)
  r      = ∫ 2μ e^(−τ/μ) R↓(μ) dμ,   R↓(μ) = ∫ f_r(w → w') |cos θ'| e^(−τ/|cos θ'|) dw'
           (the fraction of the body's Lambertian flux that the interface sends back to it,
           from below, total internal reflection included)
  Ē      = ∫ 2μ E(μ) dμ

  f(wi, wo)·cos θo = f_r(wi, wo)·cos θo + ρ/(π η²) · E(μi) E(μo) / (1 − ρ r) · cos θo.

The body's radiance ρΦ/π (Φ the flux reaching it after every round trip, E(μi)/(1 − ρr) per unit
incident flux) leaves through the interface with E(μo)/η² by the generalised reciprocity of the
interface (the 1/η²: radiance leaving a denser medium). With τ = 0, ρ = 1, a smooth interface and
no tint it conserves energy exactly (1 − r = Ē/η², the two Fresnel identities), which
tests/test_coated_diffuse.py checks together with the agreement with the walk itself.

E and R↓ are integrals of the standard dielectric's own sampler (kernels/bsdf/dielectric.py,
the same maths as the walk's interfaces): visible normals on a Fibonacci lattice, each normal's
reflection and refraction weighted by its Fresnel factor (no random choice), so the tables are
deterministic; ``integrate_node`` fills one table node (backend/layered/coated_diffuse.py calls
it and caches the tables).

Sampling: the interface's reflection lobe (visible normals, reflected; not weighted by Fresnel)
with probability w_s = Rs/(Rs + D̄) — Rs the interface's directional albedo, D̄ the body's
(channel mean) at μi — else the body's exit distribution: cos θo·E(μo) (channel mean), drawn
from a piecewise-constant table over μo² (``ES``: its NU values, mean 1; uniform in μ² is the
cosine distribution), so the body's part of a sample's weight is nearly constant (a constant
world then adds almost no noise, as on a Lambertian surface). A visible normal whose reflection
points below the surface (5.9 % of them at normal incidence for GGX α 0.25, most of them near
grazing incidence) does not end the path: the reflection is mirrored up through the surface
plane, so the top's density at wo is q_r(wo) + q_r(wo mirrored below), both exact
(``top_density``), and pdf = w_s·(that) + (1 − w_s)·h(μo²) cos θo/π. (Until 2026-12-07 such a
reflection drew from the body instead, at a share tabulated over μ, and the pdf was off where
that share changes fast, near grazing incidence: tests/test_coated_diffuse.py.) A smooth
interface's mirror reflection is a delta lobe taken with probability w_s (weight F(μi)/w_s).
The weight of a non-delta sample is eval/pdf (exact: nothing estimated).

Table block ``T[o:]`` (float64): the head [number of roughness nodes NA, 1/η², 0, 0], then NA
node blocks of NODE values: E (3 × NMU, per channel over μ = 0 … 1 in NMU uniform steps), Rs
(NMU), r (3), Ē (3), ES (NU), its running sum / NU (NU + 1). One node: the material's constant
roughness. NA > 1: the roughness is a texture and the nodes are uniform in √α over [0, 1]
(Blender's roughness slider), interpolated linearly (node 0 is the smooth interface); the exit
distribution is then the mixture of the two nodes' (each drawn with its interpolation weight).
"""
from __future__ import annotations

import math

from . import IMPORTANCE
from . import dielectric
from .. import microfacet as mf
from ..fresnel import dielectric as fresnel
from ..jit import inlined, kernel
from ..turns import cos_sin_turns

from ..consts import INV_PI
ZERO3 = (0.0, 0.0, 0.0)
NMU = 65                      # μ nodes per table (linear interpolation; tests state the error)
NU = 64                       # intervals in μ² of the exit distribution
HEAD = 4
E_AT, RS_AT, R_AT, EBAR_AT = 0, 3 * NMU, 4 * NMU, 4 * NMU + 3
ES_AT = 4 * NMU + 6
CDF_AT = ES_AT + NU
NODE = CDF_AT + NU + 1
MU_MIN = 1e-4                 # node μ = 0 is evaluated here (the visible normals degenerate at 0)
GOLDEN = 0.6180339887498949   # (√5 − 1)/2: the integrals' normals form a Fibonacci lattice


# ----------------------------------------------------------------------------- lookups
@kernel
def _mu_lerp(T, base, mu):
    x = min(max(mu, 0.0), 1.0) * (NMU - 1)
    i = min(int(x), NMU - 2)
    t = x - i
    return T[base + i] + t * (T[base + i + 1] - T[base + i])


@kernel
def _nodes(T, o, alpha):
    """(first node, second node, weight of the second) for roughness α."""
    na = int(T[o])
    first = o + HEAD
    if na <= 1:
        return first, first, 0.0
    x = min(max(math.sqrt(max(alpha, 0.0)), 0.0), 1.0) * (na - 1)
    i = min(int(x), na - 2)
    return first + i * NODE, first + (i + 1) * NODE, x - i


@kernel
def _at(T, a, b, t, off, mu):
    return (1.0 - t) * _mu_lerp(T, a + off, mu) + t * _mu_lerp(T, b + off, mu)


@kernel
def _const(T, a, b, t, off):
    return (1.0 - t) * T[a + off] + t * T[b + off]


@kernel
def _body(T, o, alpha, rho, mu_i):
    """Per channel: E(μi), the factor ρ/(π η² (1 − ρ r)), and the body's directional albedo D."""
    a, b, t = _nodes(T, o, alpha)
    inv_eta2 = T[o + 1]
    e = (_at(T, a, b, t, E_AT, mu_i), _at(T, a, b, t, E_AT + NMU, mu_i), _at(T, a, b, t, E_AT + 2 * NMU, mu_i))
    k0 = rho[0] * inv_eta2 / max(1.0 - rho[0] * _const(T, a, b, t, R_AT), 1e-3)
    k1 = rho[1] * inv_eta2 / max(1.0 - rho[1] * _const(T, a, b, t, R_AT + 1), 1e-3)
    k2 = rho[2] * inv_eta2 / max(1.0 - rho[2] * _const(T, a, b, t, R_AT + 2), 1e-3)
    d = (k0 * e[0] * _const(T, a, b, t, EBAR_AT), k1 * e[1] * _const(T, a, b, t, EBAR_AT + 1),
         k2 * e[2] * _const(T, a, b, t, EBAR_AT + 2))
    return e, (k0 * INV_PI, k1 * INV_PI, k2 * INV_PI), d, _at(T, a, b, t, RS_AT, mu_i)


SHARP_ALPHA = 0.02          # a reflection lobe this sharp or sharper is sampled at least ...
SHARP_SHARE = 0.2          # ... this often


@kernel
def specular_share(rs, d, alpha):
    """The probability of sampling the interface's own reflection: its share of the albedo, but
    at least SHARP_SHARE for a sharp lobe (α ≤ SHARP_ALPHA, smooth included). A small light
    (the sun) mirrored in a sharp lobe is found by BSDF sampling alone (light sampling rarely
    lands inside the lobe), so there the albedo share (4–10 % for a coat) leaves the highlight to
    rare samples of large weight; but every sample taken by the lobe beyond its share makes the
    rest of the surface noisier under broad light (the weights split into two values). Measured
    on a clear coat over rough gold under a 5° sun and a uniform sky (benchmarks/everyday.py,
    64², 32 spp, 8 seeds; image-wide noise, dominated by the sun's highlight / the median
    pixel's): share 0.5 13.6 % / 2.35 %, 0.25 17.8 % / 1.40 %, 0.2 18.7 % / 1.27 %, 0.15
    19.4 % / 1.12 %, the albedo share alone 20.9 % / 0.79 %; Cycles 5.0.1's Principled coat over
    gold 18.7 % / 1.14 %. 0.2 matches Cycles' highlight and keeps the surface within 1.3 %.
    Since the camera's hit takes the lights a sharp lobe meets at every sample
    (kernels/integrator.py ``_probe_lobe``), again: 0.2 13.4 % / 0.99 %, the albedo share alone
    15.9 % / 0.62 % (the presets scene's variance 30.45 against 36.35): 0.2 kept, as the lobe
    still finds every other light (the world, lit surfaces) by this choice."""
    s = rs + (d[0] + d[1] + d[2]) / 3.0
    w = rs / s if s > 0.0 else 0.5
    if alpha <= SHARP_ALPHA and rs > 0.0:
        w = max(w, SHARP_SHARE)
    return w


@kernel
def _exit(T, o, alpha, mu_o):
    a, b, t = _nodes(T, o, alpha)
    return (_at(T, a, b, t, E_AT, mu_o), _at(T, a, b, t, E_AT + NMU, mu_o), _at(T, a, b, t, E_AT + 2 * NMU, mu_o))


@kernel
def _exit_density(T, o, alpha, mu):
    """h(μ²)·μ/π: the solid-angle density of the body's exit distribution (mixture of nodes)."""
    a, b, t = _nodes(T, o, alpha)
    k = min(int(mu * mu * NU), NU - 1)
    return ((1.0 - t) * T[a + ES_AT + k] + t * T[b + ES_AT + k]) * mu * INV_PI


@kernel
def _sample_exit(T, o, alpha, u0, u1, u2):
    """A direction from the body's exit distribution: node by u2 (its interpolation weight),
    the μ² interval by inverting the running sum with u0, μ² uniform inside it, φ = 2π u1."""
    a, b, t = _nodes(T, o, alpha)
    n = b if u2 < t else a
    lo = 0
    hi = NU
    while hi - lo > 1:                          # the last k with CDF[k] ≤ u0
        mid = (lo + hi) // 2
        if T[n + CDF_AT + mid] <= u0:
            lo = mid
        else:
            hi = mid
    w = T[n + CDF_AT + lo + 1] - T[n + CDF_AT + lo]
    x = (u0 - T[n + CDF_AT + lo]) / w if w > 0.0 else 0.5
    u = (lo + min(max(x, 0.0), 1.0)) / NU
    mu = math.sqrt(min(max(u, 0.0), 1.0))
    st = math.sqrt(max(1.0 - u, 0.0))
    c, s = cos_sin_turns(u1)
    return (st * c, st * s, mu)


@kernel
def reflected_visible(dist, au, av, wi, u0, u1):
    """wi mirrored about a visible normal (it may point below the surface)."""
    m = mf.sample_visible(dist, au, av, wi, u0, u1)
    c = wi[0] * m[0] + wi[1] * m[1] + wi[2] * m[2]
    return (2.0 * c * m[0] - wi[0], 2.0 * c * m[1] - wi[1], 2.0 * c * m[2] - wi[2])


TOP_DELTA, TOP_LOBE, BODY = 0, 1, 2     # what ``top_or_body`` chose


@kernel
def top_or_body(eta, smooth, dist, au, av, w_s, wi, u0, u1, u2):
    """The split every coated sampler makes (this module's and the tables',
    kernels/bsdf/tabulated.py): with probability w_s the top interface's reflection, else the
    body's own sampler. Returns (choice, wo, F, a, b, c): TOP_DELTA for a smooth top (its weight
    F/w_s, already divided), TOP_LOBE with wo above the surface (a reflection below it mirrored
    up: ``top_density``), or BODY, whose sampler takes the three numbers (a, b, c) — u2
    rescaled past w_s."""
    if u2 < w_s:
        if smooth:
            return TOP_DELTA, (-wi[0], -wi[1], wi[2]), dielectric.smooth_reflectance(eta, True, wi) / w_s, u0, u1, u2
        return TOP_LOBE, top_lobe_sample(dist, au, av, wi, u0, u1), 0.0, u0, u1, u2
    return BODY, (0.0, 0.0, 1.0), 0.0, u0, u1, (u2 - w_s) / (1.0 - w_s)


@kernel
def top_lobe_sample(dist, au, av, wi, u0, u1):
    """A direction from the top's own sampler (``top_or_body``'s TOP_LOBE): a visible normal's
    reflection, mirrored up where it points below the surface (``top_density`` counts both ways
    in)."""
    wo = reflected_visible(dist, au, av, wi, u0, u1)
    return (wo[0], wo[1], abs(wo[2]))


@kernel
def top_density(dist, au, av, wi, wo):
    """Density of the top's sampler (``top_or_body``) at wo above the surface: a visible normal
    reflected to wo, or reflected below the surface to wo's mirror image and mirrored up. Both
    terms are exact, so the sampler's pdf is (no tabulated share of reflections lost below)."""
    d = reflection_density(dist, au, av, wi, wo)
    if wo[2] < wi[2]:           # else the half vector of wo's mirror image is not above the surface
        d += reflection_density(dist, au, av, wi, (wo[0], wo[1], -wo[2]))
    return d


@kernel
def reflection_density(dist, au, av, wi, wo):
    """Density of a visible normal reflected about: D_wi(h) / (4 |wo·h|) (the reflection's
    solid-angle Jacobian), h the half vector."""
    hx, hy, hz = wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]
    n = math.sqrt(hx * hx + hy * hy + hz * hz)
    if not n > 0.0:
        return 0.0
    h = (hx / n, hy / n, hz / n)
    c = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]
    if not c > 0.0:
        return 0.0
    return mf.pdf_visible(dist, au, av, wi, h) / (4.0 * c)


# ----------------------------------------------------------------------------- the BSDF
@kernel
def eval_pdf(T, o, eta, au, av, smooth, rho, dist, masking, wi, wo):
    """(f·cos θo RGB, pdf of ``sample``) for wi, wo above the surface (0 otherwise: the stack is
    opaque and two-sided; the integrator turns the frame towards the viewer)."""
    if not (wi[2] > 0.0 and wo[2] > 0.0):
        return ZERO3, 0.0
    e_i, k, d, rs = _body(T, o, au, rho, wi[2])
    e_o = _exit(T, o, au, wo[2])
    mo = wo[2]
    f = (k[0] * e_i[0] * e_o[0] * mo, k[1] * e_i[1] * e_o[1] * mo, k[2] * e_i[2] * e_o[2] * mo)
    w_s = specular_share(rs, d, 0.0 if smooth else au)
    if smooth:
        pdf = (1.0 - w_s) * _exit_density(T, o, au, mo)
    else:
        pdf = (1.0 - w_s) * _exit_density(T, o, au, mo)
        fr, _ = dielectric.eval_pdf(eta, (1.0, 1.0, 1.0), au, av, smooth=False, dist=dist,
                                    masking=masking, mode=IMPORTANCE, wi=wi, wo=wo)
        f = (f[0] + fr[0], f[1] + fr[1], f[2] + fr[2])
        pdf += w_s * top_density(dist, au, av, wi, wo)
    return f, pdf


@kernel
def sample(T, o, eta, au, av, smooth, rho, dist, masking, wi, u0, u1, u2):
    """(wo, weight, pdf, is_delta): the interface's reflection with probability w_s, else a
    cosine-weighted direction (see the module docstring)."""
    if not wi[2] > 0.0:
        return (0.0, 0.0, 1.0), ZERO3, 0.0, False
    _, _, d, rs = _body(T, o, au, rho, wi[2])
    w_s = specular_share(rs, d, 0.0 if smooth else au)
    choice, wo, F, a, b, c = top_or_body(eta, smooth, dist, au, av, w_s, wi, u0, u1, u2)
    if choice == TOP_DELTA:
        return wo, (F, F, F), 0.0, True
    if choice == BODY:
        wo = _sample_exit(T, o, au, a, b, c)          # the body's exit distribution
    if not wo[2] > 0.0:
        return wo, ZERO3, 0.0, False
    f, pdf = eval_pdf(T, o, eta, au, av, smooth, rho, dist, masking, wi, wo)
    if not pdf > 0.0:
        return wo, ZERO3, 0.0, False
    return wo, (f[0] / pdf, f[1] / pdf, f[2] / pdf), pdf, False


@kernel
def albedo(T, o, au, rho, mu):
    """The directional albedo at cos θ = μ (interface reflection + body): the denoising AOV."""
    _, _, d, rs = _body(T, o, au, rho, max(mu, 0.0))
    return (rs + d[0], rs + d[1], rs + d[2])


# ----------------------------------------------------------------------------- the tables
@kernel
def _interface_integrals(eta, tint, alpha, smooth, dist, masking, tau, mu, n):
    """(E per channel, Rs) at μ from above and (R↓ per channel) at μ from below, on an n²-point
    lattice of visible normals (the dielectric sampler's; each normal's reflection weighted by F
    and its refraction by 1 − F)."""
    st = math.sqrt(max(1.0 - mu * mu, 0.0))
    above = (st, 0.0, mu)
    below = (st, 0.0, -mu)
    e0 = e1 = e2 = 0.0
    rs = 0.0
    d0 = d1 = d2 = 0.0
    if smooth:
        F, ct, _ = fresnel(mu, eta)
        a = 1.0 - F
        if ct != 0.0:
            e0 = a * tint[0] * math.exp(-tau[0] / abs(ct))
            e1 = a * tint[1] * math.exp(-tau[1] / abs(ct))
            e2 = a * tint[2] * math.exp(-tau[2] / abs(ct))
        Fb = fresnel(-mu, eta)[0]
        x = 1.0 / max(mu, 1e-300)
        return (e0, e1, e2), F, (Fb * math.exp(-tau[0] * x), Fb * math.exp(-tau[1] * x), Fb * math.exp(-tau[2] * x))
    inv = 1.0 / n
    for q in range(n * n):
        # a Fibonacci lattice (a grid's points fall on n rings of tilt at normal incidence)
        u0 = (q + 0.5) * inv * inv
        u1 = (0.5 + q * GOLDEN) % 1.0
        # from above: the normal's Fresnel factor, then each branch's weight (G2/G1, tint)
        m = mf.sample_visible(dist, alpha, alpha, above, u0, u1)
        F = fresnel(above[0] * m[0] + above[1] * m[1] + above[2] * m[2], eta)[0]
        wr, vr, _, _ = dielectric.sample(eta, tint, alpha, alpha, False, dist, masking, IMPORTANCE,
                                         above, u0, u1, 0.0)
        if wr[2] > 0.0:
            rs += F * vr[0]
        if F < 1.0:
            wt, vt, _, _ = dielectric.sample(eta, tint, alpha, alpha, False, dist, masking, IMPORTANCE,
                                             above, u0, u1, 1.0)
            if wt[2] < 0.0:
                x = 1.0 / abs(wt[2])
                e0 += (1.0 - F) * vt[0] * math.exp(-tau[0] * x)
                e1 += (1.0 - F) * vt[1] * math.exp(-tau[1] * x)
                e2 += (1.0 - F) * vt[2] * math.exp(-tau[2] * x)
        # from below: what the interface reflects back down
        mb = mf.sample_visible(dist, alpha, alpha, (-below[0], -below[1], -below[2]), u0, u1)  # as the sampler: −wi
        Fb = fresnel(below[0] * mb[0] + below[1] * mb[1] + below[2] * mb[2], eta)[0]
        wb, vb, _, _ = dielectric.sample(eta, tint, alpha, alpha, False, dist, masking, IMPORTANCE,
                                         below, u0, u1, 0.0)
        if wb[2] < 0.0:
            x = 1.0 / abs(wb[2])
            d0 += Fb * vb[0] * math.exp(-tau[0] * x)
            d1 += Fb * vb[1] * math.exp(-tau[1] * x)
            d2 += Fb * vb[2] * math.exp(-tau[2] * x)
    s = inv * inv
    return (e0 * s, e1 * s, e2 * s), rs * s, (d0 * s, d1 * s, d2 * s)


@kernel(nogil=True)
def integrate_node(eta, tint, alpha, smooth, dist, masking, tau, n, gl_x, gl_w, out):
    """One table node (the module docstring's layout) into ``out`` (NODE values): E and Rs on
    the μ grid, r and Ē by Gauss–Legendre quadrature (nodes ``gl_x``, weights ``gl_w`` on
    [0, 1]) of the integrals computed at its nodes."""
    for j in range(NMU):
        mu = max(j / (NMU - 1.0), MU_MIN)
        e, rs, _ = _interface_integrals(eta, tint, alpha, smooth, dist, masking, tau, mu, n)
        for c in range(3):
            out[E_AT + c * NMU + j] = e[c]
        out[RS_AT + j] = rs
    for c in range(3):
        out[R_AT + c] = 0.0
        out[EBAR_AT + c] = 0.0
    for q in range(gl_x.shape[0]):
        mu = gl_x[q]
        e, _, d = _interface_integrals(eta, tint, alpha, smooth, dist, masking, tau, mu, n)
        w = 2.0 * mu * gl_w[q]
        for c in range(3):
            out[EBAR_AT + c] += w * e[c]
            out[R_AT + c] += w * math.exp(-tau[c] / mu) * d[c]


# ----------------------------------------------------------------------------- binding
# The kind's slots in a material row (kernels/materials.py ``MaterialTable.values``: its Python
# material packs them) and its lane parameters: the 12-tuple every kind binds to (one Numba type
# for all, kernels/materials.py ``bind``), written and read here only.
ETA, AU, AV, RHO, TAB = 3, 4, 5, 6, 9   # relative eta, α, body colour (RGB), table offset


@inlined
def params(eta, au, av, rho, tab):
    smooth = 1.0 if (au <= 0.0 and av <= 0.0) else 0.0
    return (eta, max(au, mf.ALPHA_MIN), max(av, mf.ALPHA_MIN), smooth, rho[0], rho[1], rho[2], tab,
            0.0, 0.0, 0.0, 0.0)


@inlined
def eval_pdf_p(T, p, dist, masking, wi, wo):
    return eval_pdf(T, int(p[7]), p[0], p[1], p[2], p[3] > 0.0, (p[4], p[5], p[6]), dist, masking, wi, wo)


@inlined
def sample_p(T, p, dist, masking, wi, u0, u1, u2):
    return sample(T, int(p[7]), p[0], p[1], p[2], p[3] > 0.0, (p[4], p[5], p[6]), dist, masking, wi,
                  u0, u1, u2)


@inlined
def albedo_p(T, p, mu):
    return albedo(T, int(p[7]), p[1], (p[4], p[5], p[6]), mu)


@inlined
def smooth_reflectance_p(p, wi):
    """A smooth top's mirror, as ``top_or_body`` samples it (TOP_DELTA): F on average."""
    return dielectric.smooth_reflectance(p[0], p[3] > 0.0, wi)


@inlined
def sharp_top_p(T, p, dist, wi, u0, u1):
    """For a rough top with α ≤ SHARP_ALPHA: (w_s, a direction from the top's lobe alone);
    w_s 0 for any other top (kernels/integrator.py ``_probe_lobe``)."""
    if p[3] > 0.0 or not p[1] <= SHARP_ALPHA or not wi[2] > 0.0:
        return 0.0, (0.0, 0.0, 1.0)
    _, _, d, rs = _body(T, int(p[7]), p[1], (p[4], p[5], p[6]), wi[2])
    return specular_share(rs, d, p[1]), top_lobe_sample(dist, p[1], p[2], wi, u0, u1)
