"""Caustics by light tracing: paths light → smooth glass, mirrors or sharp glossy surfaces (the
*casters*) → a surface the camera sees, traced from the light and splatted onto the film.

Why: a path tracer finds such a path only when a BSDF-sampled ray from the seen surface happens
to pass through the glass into the light's small solid angle (a sun's disk, a lamp seen through
a lens), or when a light sample at a polished metal lands in its narrow lobe, so the sun's
caustic under a glass ball is a scatter of rare, bright samples (fireflies). From the light the
same paths are easy: aim at the caster, pass through it, and connect the next surface to the
camera.

The two estimators share the work by a partition, so nothing is counted twice and nothing is
lost. A path belongs to the light tracer exactly when
  * its camera ray hits a *plain* material (``Settings.caustic_plain``: no mix, no layered stack
    that keeps the random walk, no normal map or bump) that is not a caster, and leaves it by a
    lobe that is not a delta one (a coated kind's smooth top),
  * every vertex after it up to the light is a caster of a plain material
    (``Settings.caustic_caster``: smooth dielectrics and conductors, glossy kinds with α ≤
    backend/caustics.py CAUSTIC_ALPHA, metals CAUSTIC_ALPHA_METAL), at least one and at most
    max_bounces of them, none with a shading normal the path tracer bends for its view
    direction,
  * and the light is *covered* (``CausticTables.lights``: an area light, a point or spot light,
    a sun, the emissive triangles). A point light of radius 0 or a sun of angle 0 is a delta light: the path tracer finds
    it off a glossy caster by light samples (which it then drops), never through smooth glass,
    so there the photons add light that path tracing alone leaves out (as Cycles does).
The path tracer drops exactly those paths (kernels/integrator.py: the ray leaving the camera hit
carries ``CAUSTIC_FROM``, a caster vertex reached by such a ray takes no light sample of a
covered light and no mirror probe, and its continuation carries ``CAUSTIC_CHAIN``, whose covered
lights carry nothing). This kernel traces photons from the covered lights towards spheres
around the casters (one per object), so every such path has a positive density here; a caster passes
a photon on, and the first other surface it reaches after one splats it (if the camera sees
it). Casters are not receivers: seen by the camera, a near-mirror shows a caustic by its own
reflection, which the path tracer samples well and a splat, weighted by the narrow lobe's
value, would turn into fireflies.

Estimator (one photon; N photons per render, ``FilmAccumulator``): the photon leaves light ``li``
(chosen with probability P_li) with flux Φ = L_e cos θ_e / (P_li · pdf(position, direction)),
passes the casters with the adjoint weights (importance-mode BSDF sample weight times
|ω_in·n_s||ω_out·n_g| / (|ω_in·n_g||ω_out·n_s|), Veach 1997 §5.3: shading normals), and at a
surface x adds to pixel q

    Φ · f(ω_cam, ω_in) |ω_in·n_s| / |ω_in·n_g| · |ω_cam·n_g| / r² · J · h_q(film position)

where f |ω_in·n_s| is ``materials.eval_pdf`` with the camera as the view direction (exactly what
the path tracer evaluates at its camera hit), r the distance to the pinhole, J = W H |P|³/|n·P|
the film's pixels per steradian along the ray (P: the ray's point on the film plane, n the
plane's normal × its area), and h_q the pixel filter's density at the position's offset from q's
centre (the piecewise-constant density the camera kernel's filter sampling has). The image is
the path tracer's mean plus the sum of the splats divided by N.

What restricts it (backend/caustics.py decides, per scene): a pinhole camera (no depth of field,
no camera motion), no moving geometry, no ray visibility, light or shadow linking, no Clamp
Indirect (it clamps per path sample, which a splat cannot reproduce).
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from . import materials as km
from .bsdf import IMPORTANCE, RADIANCE
from .integrator import _offset, _valid_reflection_normal, facing_viewer, static_surface, surface_uv
from .jit import inlined, kernel
from . import discrete as _discrete
from .lights import area as _area
from .lights import mesh as _mesh
from .lights import point as _point
from .lights import sun as _sun
from .lights.common import get3, sample_cone, sin2_to_one_minus_cos
from .rng import path_key, uniform
from .soup import ROW_MAT
from .trace import _aligned_block, intersect_one, occluded_one
from .vec import coordinate_system
from .vec import dot as _dot
from .vec import shading_frame as _frame
from .vec import to_local as _local
from .vec import to_world as _world
from .warp import disk_concentric, triangle_barycentric

#: What the photon kernel reads besides the scene's tables (backend/caustics.py builds it):
#:   lights     (k,) int64    the covered lights (rows of the light table)
#:   cdf        (k + 1,)      their selection distribution (∝ the flux they send at the casters)
#:   spheres    (k, 4)        caster spheres (centre xyz, radius): one per object with casters
#:   scdf       (k + 1,)      how often each is aimed at (∝ its cross-section)
#:   far        float         how far beyond a sphere a sun's photons start (beyond every triangle)
#:   proj       (PROJ_SIZE,)  the camera as a projection (columns P_* below)
#:   fcdf       (m + 1,)      the pixel filter's cumulative table (backend/film.py PixelFilter)
#:   max_casters int          caster vertices a photon may pass (max_bounces)
#:   seed       uint64        the photons' random-number seed
CausticTables = namedtuple("CausticTables", ["lights", "cdf", "spheres", "scdf", "far", "proj", "fcdf", "max_casters",
                                             "seed"])

P_O, P_TL, P_N, P_DS, P_DT, P_INV = 0, 3, 6, 9, 12, 15     # 3, 3, 3, 3, 3, 9 columns
P_NEAR, P_FAR, P_W, P_H, P_SUPPORT = 24, 25, 26, 27, 28
P_CROP = 29                     # 4: the pixels rendered, x0, y0, x1, y1 (ends excluded)
PROJ_SIZE = 33

# Photon dimensions (hashed: one photon is one sample of a 2-D-per-vertex integral, and the
# photons of a render are many; stratifying them would need a sequence over items).
D_PICK, D_POS, D_DIR, D_SPHERE, D_VERTEX = 0, 1, 3, 5, 6     # vertex k: D_VERTEX + 3k … + 2


@kernel
def _filter_density(fcdf, support, offset):
    """Density of the camera kernel's filter offsets at ``offset`` pixels (1-D): the table's
    piecewise-constant density, so that it integrates exactly as the sampling does."""
    x = offset / support + 0.5
    if not (x >= 0.0 and x < 1.0):
        return 0.0
    m = fcdf.shape[0] - 1
    k = min(int(x * m), m - 1)
    return (fcdf[k + 1] - fcdf[k]) * m / support


@kernel
def project(proj, x):
    """Film position (s, t) of point x (fractions of the width and height, as camera_rays'
    (s, t)), J = pixels per steradian along the ray, the distance r to the pinhole and the
    length the camera-facing ray from x may travel before the near clip plane; J = 0 where the
    camera cannot see x (behind it, outside the clip range)."""
    q = (x[0] - proj[P_O], x[1] - proj[P_O + 1], x[2] - proj[P_O + 2])
    r = math.sqrt(_dot(q, q))
    # depth along the view axis, in the camera's own units (the clip distances')
    depth = -(proj[P_INV + 6] * q[0] + proj[P_INV + 7] * q[1] + proj[P_INV + 8] * q[2])
    if not (r > 0.0 and depth > proj[P_NEAR] and depth < proj[P_FAR]):
        return 0.0, 0.0, 0.0, r, 0.0
    n = (proj[P_N], proj[P_N + 1], proj[P_N + 2])
    tl = (proj[P_TL], proj[P_TL + 1], proj[P_TL + 2])
    nq = _dot(n, q)
    if nq == 0.0:
        return 0.0, 0.0, 0.0, r, 0.0
    lam = _dot(n, tl) / nq
    if not lam > 0.0:
        return 0.0, 0.0, 0.0, r, 0.0
    P = (lam * q[0], lam * q[1], lam * q[2])
    e = (P[0] - tl[0], P[1] - tl[1], P[2] - tl[2])
    s = _dot(e, (proj[P_DS], proj[P_DS + 1], proj[P_DS + 2]))
    t = _dot(e, (proj[P_DT], proj[P_DT + 1], proj[P_DT + 2]))
    pl = math.sqrt(_dot(P, P))
    J = proj[P_W] * proj[P_H] * pl * pl * pl / abs(_dot(n, P))
    reach = r * (1.0 - proj[P_NEAR] / depth)
    return s, t, J, r, reach


@kernel
def _pick(cdf, u):
    """The first index k with u < cdf[k + 1] (so cdf[k] ≤ u: never an entry of probability 0;
    the last one if none), and its probability. A binary search: a scene may cover hundreds of
    lamps."""
    lo = 0
    hi = cdf.shape[0] - 2
    while lo < hi:
        mid = (lo + hi) // 2
        if u < cdf[mid + 1]:
            hi = mid
        else:
            lo = mid + 1
    return lo, cdf[lo + 1] - cdf[lo]


@kernel
def _line_density(CT, y, d):
    """Density per unit area, across direction d, of the sun photons' lines: each caster sphere
    k, aimed at with probability P_k, spreads its photons uniformly over its cross-section."""
    S_, cdf = CT.spheres, CT.scdf
    dens = 0.0
    for k in range(S_.shape[0]):
        e = (S_[k, 0] - y[0], S_[k, 1] - y[1], S_[k, 2] - y[2])
        a = _dot(e, d)
        q = (e[0] - a * d[0], e[1] - a * d[1], e[2] - a * d[2])
        r = S_[k, 3]
        if _dot(q, q) <= r * r:
            dens += (cdf[k + 1] - cdf[k]) / (math.pi * r * r)
    return dens


@kernel
def _cone(CT, k, y, widen):
    """The cone of directions from y that sphere k, its radius grown by ``widen``, fills:
    (axis, 1 − cos of its half-angle); every direction (1 − cos = 2) from inside it."""
    c = (CT.spheres[k, 0] - y[0], CT.spheres[k, 1] - y[1], CT.spheres[k, 2] - y[2])
    dist = math.sqrt(_dot(c, c))
    R = CT.spheres[k, 3] + widen
    if dist <= R:
        return (0.0, 0.0, 1.0), 2.0
    return (c[0] / dist, c[1] / dist, c[2] / dist), sin2_to_one_minus_cos((R / dist) ** 2)


@kernel
def _cone_density(CT, y, d, widen):
    """Solid-angle density of photon directions from y (an area light's point, a point light's
    centre): sphere k, aimed at with probability P_k, is reached uniformly over the cone it
    fills with its radius grown by ``widen``."""
    dens = 0.0
    for k in range(CT.spheres.shape[0]):
        axis, omc = _cone(CT, k, y, widen)
        if omc >= 2.0 or 1.0 - _dot(d, axis) <= omc:
            dens += (CT.scdf[k + 1] - CT.scdf[k]) / (2.0 * math.pi * omc)
    return dens


@inlined
def _emit_sun(LT, CT, li, pick, k, u):
    """A sun's photon: a direction in its disk (its one direction at angle 0), a line across
    it through caster sphere k."""
    P, I = LT.params, LT.iparams
    u1, u2, u3, u4 = u
    zero = (0.0, 0.0, 0.0)
    c = (CT.spheres[k, 0], CT.spheres[k, 1], CT.spheres[k, 2])
    R = CT.spheres[k, 3]
    delta = I[li, _sun.I_DELTA] != 0
    omc = P[li, _sun.S_OMC]
    toward = get3(P, li, _sun.S_DIR) if delta else sample_cone(get3(P, li, _sun.S_DIR), omc, u3, u4)
    s, t = coordinate_system(toward)
    dx, dy = disk_concentric(u1, u2)
    y = (c[0] + R * (dx * s[0] + dy * t[0]), c[1] + R * (dx * s[1] + dy * t[1]),
         c[2] + R * (dx * s[2] + dy * t[2]))
    far = CT.far + R
    o = (y[0] + far * toward[0], y[1] + far * toward[1], y[2] + far * toward[2])
    dens = _line_density(CT, y, toward)
    if not dens > 0.0:                 # y on the rim, lost to rounding
        return o, toward, zero, -1
    if delta:                          # irradiance E per unit area across the beam
        scale = 1.0 / (pick * dens)
        L = get3(P, li, _sun.S_IRRADIANCE)
    else:
        scale = 2.0 * math.pi * omc / (pick * dens)
        L = get3(P, li, _sun.S_RADIANCE)
    return o, (-toward[0], -toward[1], -toward[2]), (L[0] * scale, L[1] * scale, L[2] * scale), -1


@inlined
def _emit_point(LT, CT, li, pick, k, u):
    """A point or spot light's photon (any radius, IES profile and spot cone included)."""
    P, I = LT.params, LT.iparams
    u1, u2, u3, u4 = u
    zero = (0.0, 0.0, 0.0)
    # A point light of radius r > 0 is a line (direction d, offset b across it from the
    # centre, |b| ≤ r). Every line that meets the sphere, or the disk a soft-falloff light
    # turns towards each point it lights, passes within r of the centre, and one that also
    # meets caster sphere k has its direction in the cone of that sphere grown by r. Density
    # per steradian and unit area across d: dens(d) / (π r²).
    pos = get3(P, li, _point.P_POS)
    r = P[li, _point.P_RADIUS]
    axis, omc = _cone(CT, k, pos, r)
    d = sample_cone(axis, omc, u3, u4)
    if I[li, _point.I_SHAPE] == _point.SHAPE_DELTA:
        # radius 0: intensity I(d) from the centre, directions only (density per steradian)
        dens = _cone_density(CT, pos, d, 0.0)
        if not dens > 0.0:
            return pos, d, zero, -1
        scale = _point.directional_factor(P, I, li, LT.aux, d) / (pick * dens)
        Ie = get3(P, li, _point.P_INTENSITY)
        return pos, d, (Ie[0] * scale, Ie[1] * scale, Ie[2] * scale), -1
    s, t = coordinate_system(d)
    dx, dy = disk_concentric(u1, u2)
    y = (pos[0] + r * (dx * s[0] + dy * t[0]), pos[1] + r * (dx * s[1] + dy * t[1]),
         pos[2] + r * (dx * s[2] + dy * t[2]))
    disk = I[li, _point.I_SHAPE] != _point.SHAPE_SPHERE
    if not disk:
        # leave from the sphere's surface, on the side the line goes
        h = r * math.sqrt(max(1.0 - (dx * dx + dy * dy), 0.0))
        y = (y[0] + h * d[0], y[1] + h * d[1], y[2] + h * d[2])
    dens = _cone_density(CT, pos, d, r)
    if not dens > 0.0:
        return y, d, zero, -1
    scale = _point.directional_factor(P, I, li, LT.aux, d) * math.pi * r * r / (pick * dens)
    L = get3(P, li, _point.P_RADIANCE)
    return y, d, (L[0] * scale, L[1] * scale, L[2] * scale), li if disk else -1


@inlined
def _emit_mesh(LT, TX, CT, li, pick, k, u):
    """A photon of the emissive triangles (the mesh light): a triangle by the light's own
    distribution (∝ area × radiance), a point on it, a direction in the cone of caster sphere
    k; the exact emission there."""
    I = LT.iparams
    u1, u2, u3, u4 = u
    zero = (0.0, 0.0, 0.0)
    A, IA = LT.aux, LT.iaux
    tri, prob, u_rem = _discrete.sample_1d(A, I[li, _mesh.I_DIST_OFF], I[li, _mesh.I_COUNT], u1)
    b0, b1 = triangle_barycentric(u_rem, u2)
    b2 = 1.0 - b0 - b1
    r = I[li, _mesh.I_TRI_OFF] + tri * _mesh.TRI_STRIDE
    x = _mesh.point_at(A, r, b1, b2)
    n = (A[r + _mesh.T_N], A[r + _mesh.T_N + 1], A[r + _mesh.T_N + 2])
    axis, omc = _cone(CT, k, x, 0.0)
    d = sample_cone(axis, omc, u3, u4)
    # the emitter's cosine as its light samples take it, seen back along the photon
    cos_out = _mesh._cos_light(I, li, A, r, (-d[0], -d[1], -d[2]))
    o = _offset(x, n, d)               # off the emitter, on the side the photon leaves
    if not (cos_out > 0.0 and prob > 0.0):
        return o, d, zero, -1
    dens = _cone_density(CT, x, d, 0.0)
    if not dens > 0.0:
        return o, d, zero, -1
    le = _mesh.emitted(I, li, A, IA, TX, tri, b0, b1, b2)
    scale = cos_out * A[r + _mesh.T_AREA] / (pick * prob * dens)
    return o, d, (le[0] * scale, le[1] * scale, le[2] * scale), -1


@inlined
def _emit_area(LT, CT, li, pick, k, u):
    """An area light's photon: a point by area, a direction uniformly in the cone of caster
    sphere k."""
    P, I = LT.params, LT.iparams
    u1, u2, u3, u4 = u
    zero = (0.0, 0.0, 0.0)
    dx, dy = disk_concentric(u1, u2)
    if I[li, _area.I_ELLIPSE] != 0:
        lu, lv = dx * P[li, _area.A_HALF_U], dy * P[li, _area.A_HALF_V]
    else:
        lu, lv = (2.0 * u1 - 1.0) * P[li, _area.A_HALF_U], (2.0 * u2 - 1.0) * P[li, _area.A_HALF_V]
    # off the emitter along its normal, past a ceiling or panel it lies on (a surface's offset)
    n = get3(P, li, _area.A_N)
    y = _offset(_area._point(P, li, lu, lv), n, n)
    axis, omc = _cone(CT, k, y, 0.0)
    d = sample_cone(axis, omc, u3, u4)
    cos_out = _dot(d, n)
    if not cos_out > 0.0:
        return y, d, zero, -1
    dens = _cone_density(CT, y, d, 0.0)
    if not dens > 0.0:
        return y, d, zero, -1
    L = _area.radiance(P, I, li, cos_out)
    scale = cos_out * P[li, _area.A_AREA] / (pick * dens)
    return y, d, (L[0] * scale, L[1] * scale, L[2] * scale), -1


@kernel
def _emit(LT, TX, CT, key):
    """A photon from a covered light: (origin, direction, flux RGB already divided by the
    selection probability and the sampling density, and the light whose disk the first surface
    must see, −1 if none); flux 0 where it leaves nothing."""
    li_k, pick = _pick(CT.cdf, uniform(key, D_PICK))
    li = CT.lights[li_k]
    k, _pk = _pick(CT.scdf, uniform(key, D_SPHERE))
    u = (uniform(key, D_POS), uniform(key, D_POS + 1), uniform(key, D_DIR), uniform(key, D_DIR + 1))
    kind = LT.kind[li]
    if kind == _sun.SUN:
        return _emit_sun(LT, CT, li, pick, k, u)
    if kind == _point.POINT:
        return _emit_point(LT, CT, li, pick, k, u)
    if kind == _mesh.MESH:
        return _emit_mesh(LT, TX, CT, li, pick, k, u)
    return _emit_area(LT, CT, li, pick, k, u)


@kernel(nogil=True)
def trace_photons(tables, CT, embree, pixel0, sample0, j0, n, pix, rgb, counts):
    """Photons j0 … n−1 of the work item keyed (pixel0, sample0), while the splat buffers (pix:
    flat pixel index, rgb) have room for one more photon's worst case: it splats at one surface,
    into at most (⌊support⌋ + 2)² pixels. ``counts`` (int64[3]) out: [splats, rays traced, the
    next photon to trace (n when done)]."""
    G, MT, TX, LT, S, PS, ST = tables
    fn_hit, fn_occ, scene, offset1, rayhit = embree
    f32, w32, addr = _aligned_block(rayhit)
    R = G.rows
    count = 0
    rays = 0
    side = int(CT.proj[P_SUPPORT]) + 2
    worst = side * side
    j = j0
    while j < n and count + worst <= pix.shape[0]:
        j += 1
        key = path_key(CT.seed, pixel0, np.uint64(sample0) * np.uint64(1 << 32) + np.uint64(j - 1))
        o, d, beta, disk_light = _emit(LT, TX, CT, key)
        if not (beta[0] > 0.0 or beta[1] > 0.0 or beta[2] > 0.0):
            continue
        nd = 0
        while True:
            pr, t, b1, b2 = intersect_one(fn_hit, scene, offset1, f32, w32, addr, o, d, np.inf)
            rays += 1
            if pr < 0:
                break
            p, ng, ns, tan = static_surface(G, R, pr, b1, b2)
            if nd == 0 and disk_light >= 0:
                # a soft-falloff light lights p only along lines through the disk it turns
                # towards p (kernels/lights/point.py), as the path tracer sees it from p
                if not _point.intersect(LT.params, LT.iparams, disk_light, p, (-d[0], -d[1], -d[2]), np.inf) < np.inf:
                    break
            u, v = surface_uv(G, R, pr, b1, b2)
            m = G.irows[pr, ROW_MAT]
            if not S.caustic_plain[m]:
                break
            kind = MT.kind[m]
            prm = km.bind(MT, TX, m, u, v)
            w_in = (-d[0], -d[1], -d[2])        # towards where the photon came from
            delta = km.is_delta_only(kind, prm)
            if not S.caustic_caster[m]:
                # a surface the caustic lights (if a caster came first): seen by the camera?
                if nd > 0 and not G.holdout[pr]:
                    count, seen = _connect(MT, G, CT, fn_occ, scene, f32, w32, addr, p, ng, ns, tan, m, kind, prm,
                                           w_in, beta, pix, rgb, count)
                    rays += seen
                break
            if nd >= CT.max_casters:
                break
            # Pass the photon on (a delta vertex, or a sharp glossy caster). The path tracer's
            # view direction here is the photon's outgoing one, known only after sampling. A
            # two-sided material (a metal) reflects to the side the photon came from, so its flip
            # is taken from w_in and checked after sampling; where the path tracer would bend
            # the normal for w_out (``_valid_reflection_normal``, at grazing reflections) the
            # path stays the path tracer's (its CAUSTIC_CHAIN needs an unbent normal): the
            # photon ends.
            if MT.two_sided[m]:
                ng, ns = facing_viewer(w_in, ng, ns)
            fs, ft = _frame(ns, tan)
            wl = _local(fs, ft, ns, w_in)
            # the path tracer continues along w_in from here: its leak guard
            if not (_dot(w_in, ng) * wl[2] > 0.0):
                break
            k3 = D_VERTEX + 3 * nd
            wo, weight, _pdf, sdelta = km.sample(MT.tables, kind, MT.dist[m], MT.masking[m], prm, IMPORTANCE,
                                                 wl, uniform(key, k3), uniform(key, k3 + 1), uniform(key, k3 + 2))
            if (delta and not sdelta) or not (wo[2] != 0.0):
                break
            w_out = _world(fs, ft, ns, wo)
            if MT.two_sided[m] and not (_dot(w_out, ng) > 0.0):
                break
            if G.has_normals:
                nv = _valid_reflection_normal(w_out, ns, ng)
                if nv[0] != ns[0] or nv[1] != ns[1] or nv[2] != ns[2]:
                    break
            adj = abs(wl[2]) * abs(_dot(w_out, ng)) / (abs(_dot(w_in, ng)) * abs(wo[2]))
            beta = (beta[0] * weight[0] * adj, beta[1] * weight[1] * adj, beta[2] * weight[2] * adj)
            if not (beta[0] > 0.0 or beta[1] > 0.0 or beta[2] > 0.0):
                break
            nd += 1
            o = _offset(p, ng, w_out)
            d = w_out
    counts[0] = count
    counts[1] = rays
    counts[2] = j


@inlined
def _connect(MT, G, CT, fn_occ, scene, f32, w32, addr, p, ng, ns, tan, m, kind, prm, w_in, beta, pix, rgb, count):
    """The photon's splats at surface point p lit from w_in, if the camera sees p: (new splat
    count, rays traced)."""
    proj, fcdf = CT.proj, CT.fcdf
    s, tt, J, r, reach = project(proj, p)
    if not J > 0.0:
        return count, 0
    w_cam = ((proj[P_O] - p[0]) / r, (proj[P_O + 1] - p[1]) / r, (proj[P_O + 2] - p[2]) / r)
    # the shading frame exactly as the path tracer builds it at its camera hit
    if MT.two_sided[m]:
        ng, ns = facing_viewer(w_cam, ng, ns)
    if G.has_normals:
        ns = _valid_reflection_normal(w_cam, ns, ng)
    fs, ft = _frame(ns, tan)
    wi_l = _local(fs, ft, ns, w_cam)
    wo_l = _local(fs, ft, ns, w_in)
    cin = _dot(w_in, ng)
    if not (cin * wo_l[2] > 0.0):       # the path tracer's leak guard on its continuation
        return count, 0
    fv, _pdf = km.eval_pdf(MT.tables, kind, MT.dist[m], MT.masking[m], prm, RADIANCE, wi_l, wo_l)
    g = abs(_dot(w_cam, ng)) / (abs(cin) * r * r) * J
    c = (beta[0] * fv[0] * g, beta[1] * fv[1] * g, beta[2] * fv[2] * g)
    if not (c[0] > 0.0 or c[1] > 0.0 or c[2] > 0.0):
        return count, 0
    if not (math.isfinite(c[0]) and math.isfinite(c[1]) and math.isfinite(c[2])):
        return count, 0
    if occluded_one(fn_occ, scene, f32, w32, addr, _offset(p, ng, w_cam), w_cam, reach):
        return count, 1
    support = proj[P_SUPPORT]
    half = 0.5 * support
    W = int(proj[P_W])
    fx = s * W
    fy = tt * proj[P_H]
    x0 = max(int(math.ceil(fx - 0.5 - half)), int(proj[P_CROP]))
    x1 = min(int(math.floor(fx - 0.5 + half)), int(proj[P_CROP + 2]) - 1)
    y0 = max(int(math.ceil(fy - 0.5 - half)), int(proj[P_CROP + 1]))
    y1 = min(int(math.floor(fy - 0.5 + half)), int(proj[P_CROP + 3]) - 1)
    for py in range(y0, y1 + 1):
        hy = _filter_density(fcdf, support, fy - (py + 0.5))
        if hy == 0.0:
            continue
        for px in range(x0, x1 + 1):
            h = hy * _filter_density(fcdf, support, fx - (px + 0.5))
            if h == 0.0:
                continue
            pix[count] = py * W + px
            rgb[count, 0] = c[0] * h
            rgb[count, 1] = c[1] * h
            rgb[count, 2] = c[2] * h
            count += 1
    return count, 1
