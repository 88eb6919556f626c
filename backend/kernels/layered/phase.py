"""Phase functions of the layered media, per lane (the maths of ``backend/layered/phase``, whose
NumPy classes are wrappers over the batch loops in ``kernels/layered/batch.py``).

Conventions (as ``backend/layered/phase/__init__.py``): ``d_in``/``d_out`` are *propagation*
directions (forward scattering: d_out ≈ d_in), unit 3-tuples in the layer frame. The
connections use the BSDF-like form ``connect(a, b)``: a and b both point away from the
scattering point, returning (p(−a → b), p(−b → a)) — the value (= the sampling density) of
scattering light arriving along −a into b, and the density of the reverse choice.

A phase function's parameters sit in a float64 array ``P`` from offset ``o`` (layout ``PK`` …
below; written by ``bind_*``), so the walk reads them from its bound stack and the NumPy
wrappers from per-lane parameter rows. Every sampler is exact (weight 1) except the fiber's
rejection sampler when it gives up (weight 0, counted).

Microflake phases have a direction-dependent extinction: ``sigma_scale(d)`` (1 for the others);
σ(a)·p(a → b) = σ(b)·p(−b → −a) is the reciprocal quantity.

The fiber's projected area σ_fiber(s, θ) is read from the shipped table
(``backend/layered/phase/fiber.py`` builds it): ``FT`` is one float64 array whose rows
0 … ROWS+1 are the ghosted σ table over (ln s, q), row ``LN_ROW`` holds ln N(s), and the rows
after it are one interpolated σ row per medium with a constant stddev (so a lookup reads four
numbers instead of sixteen). float64 throughout (HG at g = 0.999 and vMF at κ = 1e4 have lobes
of ~1e-3 rad; 1 − cos θ is formed from |a ± b|², not from a dot product).
"""
from __future__ import annotations

import math

import numpy as np

from ..consts import INV_2PI, INV_4PI
from ..jit import inlined, kernel
from ..rng import uniform
from ..turns import cos_sin_turns
from .phase_layout import (  # noqa: F401 (the layout, re-exported for the kernels' callers)
    COLS, FB_AXIS, FB_CI, FB_E1, FB_E2, FB_INV_S, FB_LNNORM, FB_QSCALE, FB_ROW, FB_S, FB_W, FIBER,
    FIRST_MEDIUM_ROW, G_MAX, H_S, HG, HG_G, ISOTROPIC, KINDS, LN_ROW, LN_S0,
    MAX_CANDIDATES, PK, RAYLEIGH, ROWS, S_MAX, S_MIN, SG_B, SG_DET, SGGX, SGGX_ROUGHNESS_MIN, SIZE,
    UNIFORM_ABOVE, VMF, VMF_K, VMF_NORM)


@kernel(error_model="numpy")
def rnd(R):
    """The next number of a lane's walk stream: R = [stream key, counter] (uint64)."""
    c = R[1]
    R[1] = c + np.uint64(1)
    return uniform(R[0], c)


@kernel(error_model="numpy")
def around(ax, cos_t, sin_t, turns):
    """The direction at polar angle (cos_t, sin_t), azimuth 2π·turns about unit ``ax`` (Duff et
    al.'s frame, as backend/layered/phase/base.around)."""
    x, y, z = ax
    sign = 1.0 if z >= 0.0 else -1.0
    a = -1.0 / (sign + z)
    b = x * y * a
    cp, sp = cos_sin_turns(turns)
    sc = sin_t * cp
    ss = sin_t * sp
    return (sc * (1.0 + sign * x * x * a) + ss * b + cos_t * x,
            sc * (sign * b) + ss * (sign + y * y * a) + cos_t * y,
            -sc * (sign * x) - ss * y + cos_t * z)


@kernel(error_model="numpy")
def frame_of(ax):
    """(e1, e2) completing unit ``ax`` to an orthonormal frame (Duff et al.)."""
    x, y, z = ax
    sign = 1.0 if z >= 0.0 else -1.0
    a = -1.0 / (sign + z)
    b = x * y * a
    return (1.0 + sign * x * x * a, sign * b, -sign * x), (b, sign + y * y * a, -y)


@kernel(error_model="numpy")
def unit_or(v, fb):
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if n > 1e-12:
        return (v[0] / n, v[1] / n, v[2] / n)
    return fb


# ----------------------------------------------------------------------------- binding
@kernel(error_model="numpy")
def lagrange4(t):
    tm1 = t - 1.0
    tm2 = t - 2.0
    tp1 = t + 1.0
    return (-t * tm1 * tm2 / 6.0, tp1 * tm1 * tm2 / 2.0, -tp1 * t * tm2 / 2.0, tp1 * t * tm1 / 6.0)


@kernel(error_model="numpy")
def bind_hg(P, o, g):
    P[o + PK] = HG
    P[o + HG_G] = min(max(g, -G_MAX), G_MAX)


@kernel(error_model="numpy")
def bind_vmf(P, o, kappa):
    k = max(kappa, 0.0)
    P[o + PK] = VMF
    P[o + VMF_K] = k
    P[o + VMF_NORM] = (0.5 if k < 1e-8 else k / -math.expm1(-2.0 * k)) * INV_2PI


@kernel(error_model="numpy")
def bind_fiber(P, o, stddev, orientation, FT, row):
    """``row`` ≥ 0: the FT row precomputed for this (constant) stddev; −1: interpolate."""
    s = min(max(stddev, S_MIN), S_MAX)
    ax = unit_or(orientation, (1.0, 0.0, 0.0))
    e1, e2 = frame_of(ax)
    x = (math.log(s) - LN_S0) / H_S
    i = min(max(math.floor(x), 0.0), ROWS - 2.0)
    w = lagrange4(x - i)
    ii = int(i)
    ln_norm = (w[0] * FT[LN_ROW, ii] + w[1] * FT[LN_ROW, ii + 1] + w[2] * FT[LN_ROW, ii + 2]
               + w[3] * FT[LN_ROW, ii + 3])
    P[o + PK] = FIBER
    P[o + FB_S] = s
    P[o + FB_INV_S] = 1.0 / s
    P[o + FB_QSCALE] = (COLS - 1) / math.asinh(0.5 * math.pi / s)
    P[o + FB_LNNORM] = ln_norm
    for k in range(3):
        P[o + FB_AXIS + k] = ax[k]
        P[o + FB_E1 + k] = e1[k]
        P[o + FB_E2 + k] = e2[k]
    P[o + FB_ROW] = row
    P[o + FB_CI] = i
    for k in range(4):
        P[o + FB_W + k] = w[k]


@kernel(error_model="numpy")
def fill_fiber_row(FT, r, stddev):
    """FT[r] = σ over the (ghosted) q columns for one stddev, interpolated across the rows."""
    s = min(max(stddev, S_MIN), S_MAX)
    x = (math.log(s) - LN_S0) / H_S
    i = min(max(math.floor(x), 0.0), ROWS - 2.0)
    w = lagrange4(x - i)
    ii = int(i)
    for j in range(COLS + 2):
        FT[r, j] = w[0] * FT[ii, j] + w[1] * FT[ii + 1, j] + w[2] * FT[ii + 2, j] + w[3] * FT[ii + 3, j]


@kernel(error_model="numpy")
def sggx_preset(flake, axis, roughness):
    """S = (Sxx, Syy, Szz, Sxy, Sxz, Syz) of the fiber (flake = False) or flake preset."""
    a = unit_or(axis, (0.0, 0.0, 1.0))
    r = min(max(roughness, SGGX_ROUGHNESS_MIN), 1.0)
    r2 = r * r
    if flake:
        iso, outer = r2, 1.0 - r2
    else:
        iso, outer = 1.0, r2 - 1.0
    return (iso + outer * a[0] * a[0], iso + outer * a[1] * a[1], iso + outer * a[2] * a[2],
            outer * a[0] * a[1], outer * a[0] * a[2], outer * a[1] * a[2])


@kernel(error_model="numpy")
def bind_sggx(P, o, s6):
    """Cholesky factor B (S = B Bᵀ, lower triangular; pivots floored at 1e-300)."""
    tiny = 1e-300
    b00 = math.sqrt(max(s6[0], tiny))
    b10 = s6[3] / b00
    b20 = s6[4] / b00
    b11 = math.sqrt(max(s6[1] - b10 * b10, tiny))
    b21 = (s6[5] - b20 * b10) / b11
    b22 = math.sqrt(max(s6[2] - b20 * b20 - b21 * b21, tiny))
    P[o + PK] = SGGX
    P[o + SG_B] = b00
    P[o + SG_B + 1] = b10
    P[o + SG_B + 2] = b11
    P[o + SG_B + 3] = b20
    P[o + SG_B + 4] = b21
    P[o + SG_B + 5] = b22
    P[o + SG_DET] = b00 * b11 * b22


# ----------------------------------------------------------------------------- fiber
_ATAN = (0.9999999973285276, -0.3333330535980118, 0.19999183184538558, -0.1427485320320531,
         0.11030534828665675, -0.08719032678207402, 0.06550411135729256, -0.042188772756998234,
         0.020537157414089083, -0.006421636830539827, 0.0009420393014584832)


@kernel(error_model="numpy")
def _atan2_q1(y, x):
    """atan2(y, x) for x, y ≥ 0: an odd polynomial of degree 21 on [0, 1] (least squares at
    Chebyshev nodes; |error| < 2e-10 rad), 4× cheaper than libm's atan2 and far below the σ
    table's own interpolation error (3e-6)."""
    if y <= x:
        if x <= 0.0:
            return 0.0
        t = y / x
        flip = False
    else:
        t = x / y
        flip = True
    z = t * t
    p = _ATAN[10]
    for k in range(9, -1, -1):
        p = _ATAN[k] + z * p
    r = t * p
    return 0.5 * math.pi - r if flip else r


@kernel(error_model="numpy")
def fiber_sigma(P, o, FT, c, sn):
    """σ_fiber of the bound fiber for a direction with |cos| = c, |sin| = sn to the axis."""
    x = _atan2_q1(sn, c) * P[o + FB_INV_S]
    # asinh(x) as log(x + √(1 + x²)): a table coordinate needs absolute accuracy only, which
    # this has (≤ 2.2e-16 near x = 0); glibc's log costs about half its log1p, which was 5 % of
    # a render of the two-microflake-slab stack (perf).
    q = math.log(x + math.sqrt(1.0 + x * x)) * P[o + FB_QSCALE]
    j = min(int(q), COLS - 2)        # q ≥ 0: truncation is the floor
    wj = lagrange4(q - j)
    row = int(P[o + FB_ROW])
    if row >= 0:
        return wj[0] * FT[row, j] + wj[1] * FT[row, j + 1] + wj[2] * FT[row, j + 2] + wj[3] * FT[row, j + 3]
    i = int(P[o + FB_CI])
    out = 0.0
    for a in range(4):
        r = i + a
        out += P[o + FB_W + a] * (wj[0] * FT[r, j] + wj[1] * FT[r, j + 1] + wj[2] * FT[r, j + 2]
                                  + wj[3] * FT[r, j + 3])
    return out


@kernel(error_model="numpy")
def _fiber_scale(P, o, FT, d):
    tx, ty, tz = P[o + FB_AXIS], P[o + FB_AXIS + 1], P[o + FB_AXIS + 2]
    c = d[0] * tx + d[1] * ty + d[2] * tz
    x = d[1] * tz - d[2] * ty
    y = d[2] * tx - d[0] * tz
    z = d[0] * ty - d[1] * tx
    return 2.0 * fiber_sigma(P, o, FT, abs(c), math.sqrt(x * x + y * y + z * z))


@kernel(error_model="numpy")
def _fiber_D(P, o, x):
    s = P[o + FB_S]
    return math.exp(-x * x / (2.0 * s * s) - P[o + FB_LNNORM]) * INV_2PI


@kernel(error_model="numpy")
def _fiber_sample(P, o, FT, d_in, s_in, R, max_candidates):
    """Rejection sampling of the visible flake normal (backend/layered/phase/fiber.py):
    (d_out, weight, pdf, reverse pdf, σ-scale of d_out, candidates used)."""
    wi = (-d_in[0], -d_in[1], -d_in[2])
    t = (P[o + FB_AXIS], P[o + FB_AXIS + 1], P[o + FB_AXIS + 2])
    e1 = (P[o + FB_E1], P[o + FB_E1 + 1], P[o + FB_E1 + 2])
    e2 = (P[o + FB_E2], P[o + FB_E2 + 1], P[o + FB_E2 + 2])
    s = P[o + FB_S]
    c = wi[0] * t[0] + wi[1] * t[1] + wi[2] * t[2]
    p1 = wi[0] * e1[0] + wi[1] * e1[1] + wi[2] * e1[2]
    p2 = wi[0] * e2[0] + wi[1] * e2[1] + wi[2] * e2[2]
    sn = math.sqrt(p1 * p1 + p2 * p2)
    ac = abs(c)
    uniform_x = s > UNIFORM_ABOVE
    wa = ac * (2.0 * s * s)
    wb = sn * (s * math.sqrt(2.0 * math.pi))
    inv2s2 = 1.0 / (2.0 * s * s)
    x = 0.0
    cph = 1.0
    sph = 0.0
    done = False
    k = 0
    while k < max_candidates:
        k += 1
        u0 = rnd(R)
        u1 = rnd(R)
        u2 = rnd(R)
        u3 = rnd(R)
        u4 = rnd(R)
        if uniform_x:
            xc = 2.0 * u1 - 1.0
            lim = u3 * (ac + sn) * math.exp(xc * xc * inv2s2)
        else:
            rho = s * math.sqrt(-2.0 * math.log(1.0 - u1))     # 1 − u exact (walk.flight)
            if u0 * (wa + wb) < wa:
                xc = rho if u4 < 0.5 else -rho
            else:
                xc = rho * cos_sin_turns(u4)[0]
            lim = u3 * (ac * abs(xc) + sn)
        if abs(xc) > 1.0:
            continue
        r = math.sqrt(max(0.0, (1.0 - xc) * (1.0 + xc)))
        cp, sp = cos_sin_turns(u2)
        vis = abs(xc * c + r * (cp * p1 + sp * p2))
        if vis > lim:
            x, cph, sph = xc, cp, sp
            done = True
            break
    if not done:
        return d_in, 0.0, 0.0, 0.0, 1.0, k
    r = math.sqrt(max(0.0, (1.0 - x) * (1.0 + x)))
    mx = x * t[0] + r * (cph * e1[0] + sph * e2[0])
    my = x * t[1] + r * (cph * e1[1] + sph * e2[1])
    mz = x * t[2] + r * (cph * e1[2] + sph * e2[2])
    wm2 = 2.0 * (wi[0] * mx + wi[1] * my + wi[2] * mz)
    d_out = (wm2 * mx - wi[0], wm2 * my - wi[1], wm2 * mz - wi[2])
    D = _fiber_D(P, o, x)
    s_out = _fiber_scale(P, o, FT, d_out)
    return d_out, 1.0, D / max(s_in, 1e-300), D / max(s_out, 1e-300), s_out, k


# ----------------------------------------------------------------------------- SGGX
@kernel(error_model="numpy")
def _sggx_bt(P, o, w):
    b = o + SG_B
    return (P[b] * w[0] + P[b + 1] * w[1] + P[b + 3] * w[2],
            P[b + 2] * w[1] + P[b + 4] * w[2],
            P[b + 5] * w[2])


@kernel(error_model="numpy")
def _sggx_b(P, o, u):
    b = o + SG_B
    return (P[b] * u[0],
            P[b + 1] * u[0] + P[b + 2] * u[1],
            P[b + 3] * u[0] + P[b + 4] * u[1] + P[b + 5] * u[2])


@kernel(error_model="numpy")
def _sggx_q(P, o, h):
    """hᵀ S⁻¹ h = |B⁻¹ h|² (forward substitution)."""
    b = o + SG_B
    y0 = h[0] / P[b]
    y1 = (h[1] - P[b + 1] * y0) / P[b + 2]
    y2 = (h[2] - P[b + 3] * y0 - P[b + 4] * y1) / P[b + 5]
    return y0 * y0 + y1 * y1 + y2 * y2


@kernel(error_model="numpy")
def _sggx_scale(P, o, d):
    v = _sggx_bt(P, o, d)
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@kernel(error_model="numpy")
def sggx_distribution(P, o, m):
    """Heitz's D(m) for unit m (integrates to 4 over the sphere)."""
    q = _sggx_q(P, o, m)
    return 1.0 / (math.pi * P[o + SG_DET] * q * q)


@kernel(error_model="numpy")
def _sggx_d4(P, o, h):
    """D(ĥ)/4 for an unnormalised h; 0 where h vanishes (exact forward scattering)."""
    l2 = h[0] * h[0] + h[1] * h[1] + h[2] * h[2]
    if not l2 > 1e-24:
        return 0.0
    q = _sggx_q(P, o, h)
    return 0.25 * (l2 * l2) / (math.pi * P[o + SG_DET] * q * q)


# ----------------------------------------------------------------------------- dispatch
#: The family's kinds: code → name, and which dispatcher answers which kinds (every dispatcher
#: below has a branch for exactly these: tests/test_kind_dispatch.py).
KIND_NAMES = {code: name for name, code in KINDS.items()}
ANSWERS = {"bind": tuple(KIND_NAMES), "directional": (FIBER, SGGX), "sigma_scale": (FIBER, SGGX),
           "connect": tuple(KIND_NAMES), "sample": tuple(KIND_NAMES)}


@kernel(error_model="numpy")
def bind(P, o, kind, a, v, choice, FT, row):
    """Kind ``kind``'s block at P[o:] from a medium row's slots (backend/layered/phase_schema.py):
    the scalar ``a``, the unit-or-not vector ``v``, the choice index (SGGX: 1 = flakes), and for
    the fiber its precomputed FT ``row`` (−1: interpolate)."""
    if kind == HG:
        bind_hg(P, o, a)
    elif kind == VMF:
        bind_vmf(P, o, a)
    elif kind == FIBER:
        bind_fiber(P, o, a, v, FT, row)
    elif kind == SGGX:
        bind_sggx(P, o, sggx_preset(choice == 1, v, a))
    elif kind == ISOTROPIC or kind == RAYLEIGH:      # no parameters
        P[o + PK] = kind


@inlined(error_model="numpy")
def directional(kind):
    """Does the kind's extinction depend on the direction (``sigma_scale`` not 1)?"""
    return kind == FIBER or kind == SGGX


@kernel(error_model="numpy")
def sigma_scale(P, o, FT, d):
    """Direction-dependent extinction factor σt(d)/σt: 1 except for microflake phases."""
    kind = P[o + PK]
    if kind == FIBER:
        return _fiber_scale(P, o, FT, d)
    if kind == SGGX:
        return _sggx_scale(P, o, d)
    return 1.0


@kernel(error_model="numpy")
def _hg_value(g, omc, opc):
    # 1 + g² − 2g cos θ in the form that does not cancel: (1 − g)² + 2g(1 − cos) for g ≥ 0,
    # (1 + g)² − 2g(1 + cos) for g < 0; ≥ (1 − |g|)² ≥ 1e-6 by the clamp.
    if g >= 0.0:
        den = (1.0 - g) * (1.0 - g) + 2.0 * g * omc
    else:
        den = (1.0 + g) * (1.0 + g) - 2.0 * g * opc
    return (1.0 - g * g) * INV_4PI / (den * math.sqrt(den))


@kernel(error_model="numpy")
def _rayleigh_value(cos_t):
    """Rayleigh scattering (particles much smaller than the wavelength, unpolarised light):
    3 (1 + cos²θ) / (16π)."""
    return 3.0 * (1.0 + cos_t * cos_t) * (INV_4PI * 0.25)


@kernel(error_model="numpy")
def _rayleigh_cos(u):
    """The exact inverse of the Rayleigh CDF in μ = cos θ, F(μ) = (μ³ + 3μ + 4)/8: with
    z = 4u − 2 the depressed cubic μ³ + 3μ − 2z = 0 has the one real root A − 1/A,
    A = ∛(z + √(z² + 1)) (Cardano; A > 0, and A − 1/A is monotonic in z)."""
    z = 4.0 * u - 2.0
    A = math.pow(z + math.sqrt(z * z + 1.0), 1.0 / 3.0)
    return min(max(A - 1.0 / A, -1.0), 1.0)


@kernel(error_model="numpy")
def connect(P, o, FT, a, b, s_a, s_b):
    """(p(−a → b), p(−b → a)) for a, b pointing away from the scattering point. ``s_a``, ``s_b``:
    sigma_scale of a and b (read only by microflake phases)."""
    kind = P[o + PK]
    if kind == ISOTROPIC:
        return INV_4PI, INV_4PI
    hx = a[0] + b[0]
    hy = a[1] + b[1]
    hz = a[2] + b[2]
    if kind == HG:
        # With a, b pointing away: 1 − cos θ = |a + b|²/2, 1 + cos θ = |a − b|²/2.
        omc = 0.5 * (hx * hx + hy * hy + hz * hz)
        dx, dy, dz = a[0] - b[0], a[1] - b[1], a[2] - b[2]
        v = _hg_value(P[o + HG_G], omc, 0.5 * (dx * dx + dy * dy + dz * dz))
        return v, v
    if kind == VMF:
        omc = 0.5 * (hx * hx + hy * hy + hz * hz)
        v = P[o + VMF_NORM] * math.exp(-P[o + VMF_K] * omc)
        return v, v
    if kind == RAYLEIGH:
        v = _rayleigh_value(1.0 - 0.5 * (hx * hx + hy * hy + hz * hz))
        return v, v
    if kind == FIBER:
        l2 = hx * hx + hy * hy + hz * hz
        if not l2 > 1e-24:
            return 0.0, 0.0
        x = hx * P[o + FB_AXIS] + hy * P[o + FB_AXIS + 1] + hz * P[o + FB_AXIS + 2]
        s = P[o + FB_S]
        d = math.exp(-(x * x) / (l2 * (2.0 * s * s)) - P[o + FB_LNNORM]) * INV_2PI
        return d / max(s_a, 1e-300), d / max(s_b, 1e-300)
    if kind == SGGX:
        d = _sggx_d4(P, o, (hx, hy, hz))
        return d / max(s_a, 1e-300), d / max(s_b, 1e-300)
    return 0.0, 0.0


@kernel(error_model="numpy")
def evaluate(P, o, FT, d_in, d_out):
    """p(d_in → d_out) (= its sampling density)."""
    a = (-d_in[0], -d_in[1], -d_in[2])
    kind = P[o + PK]
    s_a = 1.0
    if directional(kind):
        s_a = sigma_scale(P, o, FT, a)
    return connect(P, o, FT, a, d_out, s_a, 1.0)[0]


@kernel(error_model="numpy")
def sample(P, o, FT, d_in, s_in, R, max_candidates):
    """(d_out, weight, pdf, reverse pdf p(−d_out → −d_in), sigma_scale(d_out), candidates).
    ``s_in`` = sigma_scale(d_in) (microflake phases). Weight 1, or 0 for a failed fiber sample."""
    kind = P[o + PK]
    if kind == ISOTROPIC:
        z = 1.0 - 2.0 * rnd(R)
        r = math.sqrt(max(0.0, (1.0 - z) * (1.0 + z)))
        cp, sp = cos_sin_turns(rnd(R))
        return (r * cp, r * sp, z), 1.0, INV_4PI, INV_4PI, 1.0, 1
    if kind == HG:
        g = P[o + HG_G]
        # Inverse CDF without a 1/g: with a = 1 + g b,
        # 1 − cos θ = (1 − g)²(1 − b)(1 + g + a)/(2a²), 1 + cos θ = (1 + g)²(1 + b)(1 − g + a)/(2a²),
        # and the density from the sampled angle: p = a³/(4π (1 − g²)²).
        b = 1.0 - 2.0 * rnd(R)
        a = 1.0 + g * b
        inv = 0.5 / (a * a)
        omc = (1.0 - g) * (1.0 - g) * (1.0 - b) * (1.0 + g + a) * inv
        opc = (1.0 + g) * (1.0 + g) * (1.0 + b) * (1.0 - g + a) * inv
        cos_t = min(max(0.5 * (opc - omc), -1.0), 1.0)
        sin_t = math.sqrt(max(omc * opc, 0.0))
        d = around(d_in, cos_t, sin_t, rnd(R))
        one_g2 = 1.0 - g * g
        p = a * a * a * (INV_4PI / (one_g2 * one_g2))
        return d, 1.0, p, p, 1.0, 1
    if kind == VMF:
        k = P[o + VMF_K]
        u0 = rnd(R)
        if k < 1e-8:
            omc = 2.0 * u0
        else:
            omc = -math.log1p(u0 * math.expm1(-2.0 * k)) / k
        omc = min(max(omc, 0.0), 2.0)
        d = around(d_in, 1.0 - omc, math.sqrt(omc * (2.0 - omc)), rnd(R))
        v = evaluate(P, o, FT, d_in, d)
        return d, 1.0, v, v, 1.0, 1
    if kind == RAYLEIGH:
        cos_t = _rayleigh_cos(rnd(R))
        d = around(d_in, cos_t, math.sqrt(max(0.0, (1.0 - cos_t) * (1.0 + cos_t))), rnd(R))
        v = _rayleigh_value(cos_t)
        return d, 1.0, v, v, 1.0, 1
    if kind == FIBER:
        return _fiber_sample(P, o, FT, d_in, s_in, R, max_candidates)
    if kind == SGGX:
        # SGGX visible normals: u cosine-distributed about normalise(Bᵀωi), m = normalise(B u).
        wi = (-d_in[0], -d_in[1], -d_in[2])
        ax = unit_or(_sggx_bt(P, o, wi), (0.0, 0.0, 1.0))
        u0 = rnd(R)
        v = around(ax, math.sqrt(1.0 - u0), math.sqrt(u0), rnd(R))
        m = unit_or(_sggx_b(P, o, v), (0.0, 0.0, 1.0))
        c2 = 2.0 * (wi[0] * m[0] + wi[1] * m[1] + wi[2] * m[2])
        d_out = (c2 * m[0] - wi[0], c2 * m[1] - wi[1], c2 * m[2] - wi[2])
        h = (d_out[0] - d_in[0], d_out[1] - d_in[1], d_out[2] - d_in[2])
        ln = math.sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2])
        s_out = _sggx_scale(P, o, d_out)
        if not ln > 1e-12:
            return d_out, 1.0, 0.0, 0.0, s_out, 1
        dd = sggx_distribution(P, o, (h[0] / ln, h[1] / ln, h[2] / ln)) * 0.25
        s_i = s_in if s_in > 0.0 else _sggx_scale(P, o, d_in)
        return d_out, 1.0, dd / max(s_i, 1e-300), dd / max(s_out, 1e-300), s_out, 1
    return d_in, 0.0, 0.0, 0.0, 1.0, 1
