"""Area lights per lane (rectangle, square, disk, ellipse), as Cycles ≥ 4.0, plus directional
area lights and the collimated (spread 0) limit.

Geometry (src/scene/light.cpp): the emitter is centred on the object's origin, spans
``size`` × ``size_y`` along the object's local X and Y *including the object's scale* (Blender's
``Light.area(matrix_world=...)``), and emits from one side, towards local −Z. Shear is ignored
(the Y axis is orthogonalised against X). Emitter coordinates (lu, lv, h) of a point are its
components along the unit axes u, v and the emission normal n, relative to the centre.

Units: with ``normalize`` (default) the radiance scale is L0 = P / (π A_world), so a Lambertian
emitter radiates exactly P watts; without it L0 = P/π (Cycles' ``invarea`` = 1). The radiance
leaving at angle θ to the normal is ``A_SCALE`` × f(θ) with ``A_SCALE`` = L0/K (profiles.py).

Angular profile (profiles.py): ``spread`` (Blender's area light spread, Cycles' soft-box
falloff), or ``cutoff_angle`` / ``beam_width`` (the directional area light, smoothstep in
angle). spread = 0 is Cycles' collimated limit (``sample_collimated``): a delta light shining
straight down the normal; a point in front of the emitter whose projection falls on it receives
the irradiance P/A × colour (P × colour without ``normalize``) from direction −n.

Sampling for next-event estimation (``plan``): only the part of the emitter that can reach the
shading point is sampled. A point at height h in front of the light receives light only from the
disk of radius h·tan(cutoff) around its projection; a point whose disk box misses the emitter
gets no sample at all (value 0, no shadow ray). Otherwise the smallest of these is sampled: the
cutoff cone of directions itself, ∝ the emitted power (the cone table; its footprint is that
disk), the disk's bounding box clipped to the emitter, uniformly in solid angle (spherical
rectangle, Ureña et al. 2013), or a whole ellipse by area. Below ``MIN_SOLID_ANGLE`` the
spherical rectangle gives way to uniform area sampling of the same box. ``pdf_hit`` redoes the
same choice, so MIS sees the exact density. float64 throughout: the solid angle of a small light
far away (1e-8 sr) is a difference of angles.
"""
from __future__ import annotations

import math

from .. import spherical_rect as _sr
from ..jit import kernel
from ..vec import dot
from ..warp import disk_concentric
from . import profiles as _prof
from .common import FIRST, I_FIRST, INF, ZERO3, get3, unit_or_zero

# Kind codes (unique within the family: dispatch.py KINDS).
AREA = 1           # rectangle / ellipse emitter with an angular profile
COLLIMATED = 2     # area light with spread 0: a delta light along the normal

# Below this solid angle [sr] the spherical-rectangle map is no better than area sampling and
# its angles lose relative precision: sample by area instead.
MIN_SOLID_ANGLE = 1e-8
# Area sampling of a whole rectangle where it is almost as good as solid-angle sampling. The
# area density in solid angle, r²/(A cos θ) = r³/(A h), varies over the rectangle by
# q = (r_max / r_min)³ (nearest point to farthest corner); the variance of area sampling
# relative to uniform solid-angle sampling is then at most (1 + q)²/(4q) (Kantorovich), 1.125 at
# q = 2, and far less where the density is not bimodal. Area sampling needs no arcsin, sine or
# cosine (the spherical rectangle costs ~100 ns a sample). Measured on the Cornell boxes of the
# benchmarks (96², 256 spp): per-pixel sample variance +0.1 % (mean) / +0.9 % (median) against
# q = 1.3, and shading 246 -> 207-215 ns a lane (the whole floor, the spheres and the lower walls
# switch). Squared-distance ratio for q = 2:
AREA_SAMPLING_R2_RATIO = 2.0 ** (2.0 / 3.0)

MODE_NONE, MODE_SPHRECT, MODE_AREA_RECT, MODE_ELLIPSE, MODE_CONE = 0, 1, 2, 3, 4

# float columns
A_CENTER = FIRST         # 3 [m]
A_U = FIRST + 3          # 3: unit axis u (local X)
A_V = FIRST + 6          # 3: unit axis v (local Y orthogonalised against X)
A_N = FIRST + 9          # 3: unit emission normal (local −Z)
A_HALF_U = FIRST + 12    # half extents along u, v [m] (world, scale included)
A_HALF_V = FIRST + 13
A_AREA = FIRST + 14      # [m²]
A_SCALE = FIRST + 15     # 3: L0/K [W m⁻² sr⁻¹]; collimated: the irradiance [W/m²]
A_TAN_MAX = FIRST + 18   # tan(cutoff) of the profile, inf without a cutoff
A_SPREAD_TAN = FIRST + 19    # SPREAD: tan(spread/2)
A_CUTOFF = FIRST + 20    # SMOOTH_CONE: cutoff, beam [rad]
A_BEAM = FIRST + 21
A_MU_LO = FIRST + 22     # cone table: lowest μ = cos θ and bin width in μ
A_WIDTH = FIRST + 23

# int columns
I_ELLIPSE = I_FIRST
I_EMITS = I_FIRST + 1    # 0: zero area or power (never sampled or hit)
I_PROFILE = I_FIRST + 2  # profiles.LAMBERTIAN / SPREAD / SMOOTH_CONE
I_CONE_OFF = I_FIRST + 3     # aux offset of the cone table
I_CONE_BINS = I_FIRST + 4    # 0: no cone table (no cutoff)

_NO_RECT = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@kernel
def _local(P, li, x):
    c = get3(P, li, A_CENTER)
    r = (x[0] - c[0], x[1] - c[1], x[2] - c[2])
    return dot(r, get3(P, li, A_U)), dot(r, get3(P, li, A_V)), dot(r, get3(P, li, A_N))


@kernel
def _point(P, li, lu, lv):
    c = get3(P, li, A_CENTER)
    u = get3(P, li, A_U)
    v = get3(P, li, A_V)
    return (c[0] + lu * u[0] + lv * v[0], c[1] + lu * u[1] + lv * v[1], c[2] + lu * u[2] + lv * v[2])


@kernel
def inside(P, I, li, lu, lv):
    hu = P[li, A_HALF_U]
    hv = P[li, A_HALF_V]
    if I[li, I_ELLIPSE] != 0:
        a = lu / hu if hu != 0.0 else 0.0
        b = lv / hv if hv != 0.0 else 0.0
        return a * a + b * b <= 1.0
    return abs(lu) <= hu and abs(lv) <= hv


@kernel
def radiance(P, I, li, cos_out):
    """Radiance leaving the emitter at cos θ to its normal."""
    f = _prof.evaluate(I[li, I_PROFILE], P[li, A_SPREAD_TAN], P[li, A_CUTOFF], P[li, A_BEAM], cos_out)
    return (P[li, A_SCALE] * f, P[li, A_SCALE + 1] * f, P[li, A_SCALE + 2] * f)


@kernel
def plan(P, I, li, p):
    """The sampling choice at point p: (mode, pu, pv, h, region u0, u1, v0, v1 in emitter
    coordinates, spherical rectangle (MODE_SPHRECT), its solid angle [sr] or 0)."""
    pu, pv, h = _local(P, li, p)
    hu = P[li, A_HALF_U]
    hv = P[li, A_HALF_V]
    u0, u1, v0, v1 = -hu, hu, -hv, hv
    tan_max = P[li, A_TAN_MAX]
    clipped = tan_max < INF
    rc = 0.0
    if clipped:
        # Only the disk of radius h·tan(cutoff) around the projection can reach p.
        rc = max(h, 0.0) * tan_max
        u0 = max(u0, pu - rc)
        u1 = min(u1, pu + rc)
        v0 = max(v0, pv - rc)
        v1 = min(v1, pv + rc)
    mode = MODE_NONE
    if h > 0.0 and u1 > u0 and v1 > v0 and I[li, I_EMITS] != 0:
        mode = MODE_SPHRECT
        box = (u1 - u0) * (v1 - v0)
        area = P[li, A_AREA]
        ellipse = I[li, I_ELLIPSE] != 0
        if ellipse and not box < area:
            mode = MODE_ELLIPSE          # whole ellipse by area unless the cone's box is smaller
        if clipped:
            # The cone itself (sampled ∝ the emitted power) when its footprint disk is smaller
            # than the box the other modes would sample: no waste when it lies on the emitter.
            if math.pi * rc * rc < (min(box, area) if ellipse else box):
                mode = MODE_CONE
    sr = _NO_RECT
    solid = 0.0
    if mode == MODE_SPHRECT:
        # corner (u0, v0) relative to p; only |z0| matters to the spherical rectangle
        sr = _sr.spherical_rect(u0 - pu, v0 - pv, -h, u1 - u0, v1 - v0)
        solid = sr[8]
        if solid < MIN_SOLID_ANGLE:
            mode = MODE_AREA_RECT
            solid = 0.0
    return mode, pu, pv, h, u0, u1, v0, v1, sr, solid


@kernel
def _whole_rect(P, I, li):
    """The common case, a rectangle with no cutoff cone: every point in front of it samples
    the whole emitter (plan() would choose MODE_SPHRECT or MODE_AREA_RECT on the full box)."""
    return I[li, I_ELLIPSE] == 0 and not P[li, A_TAN_MAX] < INF


@kernel
def _rect_frame(P, li, p):
    """Coordinates (x0, y0, z0) of the corner (−hu, −hv) relative to p in the frame
    (u, v, w = u × v), the emission normal in that frame, and w."""
    c = get3(P, li, A_CENTER)
    U = get3(P, li, A_U)
    V = get3(P, li, A_V)
    N = get3(P, li, A_N)
    W = (U[1] * V[2] - U[2] * V[1], U[2] * V[0] - U[0] * V[2], U[0] * V[1] - U[1] * V[0])
    r = (c[0] - p[0], c[1] - p[1], c[2] - p[2])
    x0 = dot(r, U) - P[li, A_HALF_U]
    y0 = dot(r, V) - P[li, A_HALF_V]
    z0 = dot(r, W)
    return x0, y0, z0, (dot(N, U), dot(N, V), dot(N, W)), U, V, W


@kernel
def _nearly_uniform(x0, y0, z0, lx, ly):
    """True where area sampling of the rectangle [x0, x0 + lx] × [y0, y0 + ly] at height z0 (seen
    from the origin) is within AREA_SAMPLING_R2_RATIO of uniform in solid angle."""
    x1 = x0 + lx
    y1 = y0 + ly
    z2 = z0 * z0
    cx = min(max(0.0, x0), x1)
    cy = min(max(0.0, y0), y1)
    fx = max(abs(x0), abs(x1))
    fy = max(abs(y0), abs(y1))
    return fx * fx + fy * fy + z2 <= AREA_SAMPLING_R2_RATIO * (cx * cx + cy * cy + z2)


@kernel
def _sample_whole_rect(P, I, li, p, u0, u1):
    """``sample`` for ``_whole_rect`` lights, all in the spherical-rectangle frame: no region
    plan, no round trip through emitter and world coordinates (measured 214 → see
    benchmarks/light_kernels.md)."""
    x0, y0, z0, n, U, V, W = _rect_frame(P, li, p)
    lx = 2.0 * P[li, A_HALF_U]
    ly = 2.0 * P[li, A_HALF_V]
    h = -(x0 * n[0] + y0 * n[1] + z0 * n[2])          # height of p in front of the emitter
    if not (h > 0.0 and I[li, I_EMITS] != 0):
        return ZERO3, 0.0, ZERO3, 0.0
    by_area = _nearly_uniform(x0, y0, z0, lx, ly)
    solid = 0.0
    sr = _NO_RECT
    if not by_area:
        sr = _sr.spherical_rect(x0, y0, z0, lx, ly)
        solid = sr[8]
        by_area = solid < MIN_SOLID_ANGLE
    if by_area:
        xu = x0 + u0 * lx                              # nearly uniform, or tiny: by area
        yv = y0 + u1 * ly
        t = math.sqrt(xu * xu + yv * yv + z0 * z0)
        inv_t = 1.0 / t if t > 0.0 else 0.0
    else:
        xu, yv, t, inv_t = _sr.sample_point(sr, u0, u1)
    if not t > 0.0:
        return ZERO3, 0.0, ZERO3, 0.0
    w = (xu * inv_t, yv * inv_t, z0 * inv_t)
    cos_out = -(w[0] * n[0] + w[1] * n[1] + w[2] * n[2])
    if not cos_out > 0.0:
        return ZERO3, 0.0, ZERO3, 0.0
    if by_area:
        pdf = t * t / (cos_out * P[li, A_AREA])
        inv = 1.0 / pdf
    else:
        pdf = 1.0 / solid
        inv = solid
    le = radiance(P, I, li, cos_out)
    wi = (w[0] * U[0] + w[1] * V[0] + w[2] * W[0], w[0] * U[1] + w[1] * V[1] + w[2] * W[1],
          w[0] * U[2] + w[1] * V[2] + w[2] * W[2])
    return wi, t, (le[0] * inv, le[1] * inv, le[2] * inv), pdf


@kernel
def sample(P, I, li, aux, p, u0, u1):
    """(wi, dist, value = radiance/pdf, solid-angle pdf); value and pdf 0 where p gets nothing."""
    if _whole_rect(P, I, li):
        return _sample_whole_rect(P, I, li, p, u0, u1)
    mode, pu, pv, h, a0, a1, b0, b1, sr, solid = plan(P, I, li, p)
    if mode == MODE_NONE:
        return ZERO3, 0.0, ZERO3, 0.0
    ellipse = I[li, I_ELLIPSE] != 0
    check_inside = ellipse
    pdf = 0.0            # solid angle; the area modes convert below
    area_pdf = 0.0
    lu = 0.0
    lv = 0.0
    if mode == MODE_SPHRECT:
        xu, yv = _sr.sample(sr, u0, u1)
        lu = pu + xu
        lv = pv + yv
        x = _point(P, li, lu, lv)
        pdf = 1.0 / solid
    elif mode == MODE_AREA_RECT:
        lu = a0 + u0 * (a1 - a0)
        lv = b0 + u1 * (b1 - b0)
        x = _point(P, li, lu, lv)
        ra = (a1 - a0) * (b1 - b0)
        area_pdf = 1.0 / ra if ra != 0.0 else 0.0
    elif mode == MODE_ELLIPSE:
        dx, dy = disk_concentric(u0, u1)
        lu = dx * P[li, A_HALF_U]
        lv = dy * P[li, A_HALF_V]
        x = _point(P, li, lu, lv)
        area_pdf = 1.0 / P[li, A_AREA]
        check_inside = False         # inside by construction
    else:
        # MODE_CONE: emission direction e at cos μ to the normal; the ray from p goes along −e
        mu, phi, pdf = _prof.cone_sample(aux, I[li, I_CONE_OFF], I[li, I_CONE_BINS], P[li, A_MU_LO],
                                         P[li, A_WIDTH], u0, u1)
        s = math.sqrt(max(0.0, 1.0 - mu * mu))
        sc = s * math.cos(phi)
        ss = s * math.sin(phi)
        n = get3(P, li, A_N)
        u = get3(P, li, A_U)
        v = get3(P, li, A_V)
        k = h / mu
        x = (p[0] - k * (mu * n[0] + sc * u[0] + ss * v[0]),
             p[1] - k * (mu * n[1] + sc * u[1] + ss * v[1]),
             p[2] - k * (mu * n[2] + sc * u[2] + ss * v[2]))
        lu, lv, _ = _local(P, li, x)
        check_inside = True          # cone directions may miss the emitter
    wi, t = unit_or_zero((x[0] - p[0], x[1] - p[1], x[2] - p[2]))
    cos_out = -dot(wi, get3(P, li, A_N))
    if area_pdf > 0.0:
        pdf = area_pdf * t * t / cos_out if cos_out != 0.0 else 0.0
    if not (t > 0.0 and cos_out > 0.0 and pdf > 0.0):
        return wi, 0.0, ZERO3, 0.0
    if check_inside and not inside(P, I, li, lu, lv):
        return wi, 0.0, ZERO3, 0.0
    le = radiance(P, I, li, cos_out)
    inv = 1.0 / pdf
    return wi, t, (le[0] * inv, le[1] * inv, le[2] * inv), pdf


@kernel
def intersect(P, I, li, o, d, tmax):
    # Every ray of the render is tested against every area light: the direction test first
    # (half the rays head away from the emitting side), then the point's height.
    denom = dot(d, get3(P, li, A_N))
    if not (denom < 0.0 and I[li, I_EMITS] != 0):
        return INF
    ou, ov, h = _local(P, li, o)
    if not h > 0.0:
        return INF
    t = h / -denom
    lu = ou + t * dot(d, get3(P, li, A_U))       # emitter coordinates of o + t·d
    lv = ov + t * dot(d, get3(P, li, A_V))
    if t > 0.0 and t < tmax and inside(P, I, li, lu, lv):
        return t
    return INF


@kernel
def eval_hit(P, I, li, o, d, t):
    return radiance(P, I, li, -dot(d, get3(P, li, A_N)))


@kernel
def pdf_hit(P, I, li, aux, o, d, t):
    """Solid-angle density of ``sample(o)`` for direction d hitting the emitter at o + t d."""
    cos_out = -dot(d, get3(P, li, A_N))
    if not cos_out > 0.0:
        return 0.0
    if _whole_rect(P, I, li):
        x0, y0, z0, n, _, _, _ = _rect_frame(P, li, o)
        if not (-(x0 * n[0] + y0 * n[1] + z0 * n[2]) > 0.0 and I[li, I_EMITS] != 0):
            return 0.0
        lx = 2.0 * P[li, A_HALF_U]
        ly = 2.0 * P[li, A_HALF_V]
        if _nearly_uniform(x0, y0, z0, lx, ly):
            return t * t / (P[li, A_AREA] * cos_out)
        solid = _sr.spherical_rect(x0, y0, z0, lx, ly)[8]
        if solid < MIN_SOLID_ANGLE:
            return t * t / (P[li, A_AREA] * cos_out)
        return 1.0 / solid
    mode, pu, pv, h, a0, a1, b0, b1, sr, solid = plan(P, I, li, o)
    if mode == MODE_NONE:
        return 0.0
    if mode == MODE_CONE:
        return _prof.cone_pdf(aux, I[li, I_CONE_OFF], I[li, I_CONE_BINS], P[li, A_MU_LO], P[li, A_WIDTH], cos_out)
    if mode == MODE_ELLIPSE:
        return t * t / (P[li, A_AREA] * cos_out)
    if P[li, A_TAN_MAX] < INF:
        # a clipped region: the hit must lie in it (computed as ``intersect`` does)
        lu = pu + t * dot(d, get3(P, li, A_U))
        lv = pv + t * dot(d, get3(P, li, A_V))
        if not (lu >= a0 and lu <= a1 and lv >= b0 and lv <= b1):
            return 0.0
    if mode == MODE_SPHRECT:
        return 1.0 / solid
    ra = (a1 - a0) * (b1 - b0)
    return t * t / (ra * cos_out) if ra != 0.0 else 0.0


@kernel
def sample_collimated(P, I, li, p):
    """Spread 0: irradiance ``A_SCALE`` along −n where p's projection falls on the emitter."""
    pu, pv, h = _local(P, li, p)
    n = get3(P, li, A_N)
    wi = (-n[0], -n[1], -n[2])
    if h > 0.0 and inside(P, I, li, pu, pv):
        return wi, h, get3(P, li, A_SCALE), 0.0
    return wi, 0.0, ZERO3, 0.0
