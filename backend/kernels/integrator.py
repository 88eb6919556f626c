"""The path tracer's per-bounce kernels: everything between two embree calls, one loop body per
lane (wavefront over work queues, in the manner of pbrt-v4's wavefront integrator).

Per bounce, for every lane whose ray embree has just traced (``shade``):
  1. emission the ray passed: hittable lights are transparent (as in Cycles), so every light the
     segment crosses before the surface adds its radiance, MIS-weighted against light sampling;
     rays that escape see the infinite lights (sun disk, world);
  2. the surface: hit point from barycentrics in float64, geometric and shading normals, UV,
     tangent; holdouts; emission of the surface (MIS with the mesh light);
  3. the shading frame (two-sided materials face the viewer; shading normals bent so the mirror
     direction stays above the geometry), AOVs at the camera hit;
  4. next-event estimation: pick a light (power or local selection), sample it, evaluate the BSDF
     and the MIS weight (power heuristic), write a shadow ray with its contribution; with 2-4
     lights (``S.nee_all``) an analytic material samples every light instead (one shadow ray
     each), and the next ray remembers which (``VIA_*``) for the MIS weight of a light it hits;
  5. continuation: sample the BSDF, Russian roulette, write the next ray (compacted).
Lanes on multi-interface layered stacks (kind LAYERED) run steps 4b and 5 through one per-lane
call (``kernels/layered/batch.shade_lane``: the light connection and the continuation sample
from shared random walks), then the same ``_nee`` and ``_continue``.

Path length: ``max_bounces`` has Cycles' meaning (0 = direct lighting only): a path has at most
max_bounces + 2 segments (camera → … → light). Precision: shading state float64; rays go to
embree as float32 (written here, so no conversion pass).
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from . import bump as _bump
from . import materials as km
from .jit import inlined, kernel
from .layered import batch as layered
from .layered.table import H_BUMP
from .lights import dispatch as ld
from .lights import mesh as _mesh
from .lights.common import C_POWER
from .mis import power_heuristic
from .rng import DIM_NEXT_LIGHT, SLOT_BSDF, SLOT_LIGHT, SLOT_LIGHT_PICK, SLOT_MIX, SLOT_RR, bounce_dim, uniform
from .sampler import get2, pixel_seed
from .soup import ROW_EMIT, ROW_MAT, ROW_N, ROW_NG, ROW_TAN, ROW_UV, ROW_V
from .textures import lookup_gradient
from .vec import cross as _cross
from .vec import dot as _dot
from .vec import shading_frame as _frame
from .vec import to_local as _local
from .vec import to_world as _world

SHADOW_EPS = 1e-4   # shadow rays stop this fraction short of the light (not its own surface)
# Ray offsets (geometry/accel.py): along the geometric normal by a multiple of the float32
# spacing at the point's magnitude, 2^-16 ≈ 1.5e-5 relative (~128 ulps), 1e-7 m absolute.
OFFSET_RELATIVE = 2.0 ** -16
OFFSET_ABSOLUTE = 1e-7
INF = np.inf

# Scene geometry for shading: one float32 row per triangle (kernels/soup.py, ``ROW_*``: corners,
# corner normals and UVs, geometric normal, tangent) and the same memory as int32 (material,
# emitter); a value at barycentrics (b1, b2) is c0 + b1·(c1 − c0) + b2·(c2 − c0) in float64.
# moving_start: the first moving triangle (motion blur; past the last triangle when none moves);
# mv, mn: their corners and shading normals at each motion step, float32 (K, M, 9).
Geometry = namedtuple("Geometry", ["rows", "irows", "holdout", "has_normals", "has_uvs",
                                   "moving_start", "mv", "mn"])
# Render settings the kernels read (scalars; one Numba type per field).
Settings = namedtuple("Settings", ["seed", "max_segments", "rr_depth", "clamp", "transparent",
                                   "has_lights", "mesh_light", "hittable", "infinite",
                                   "visible_camera", "sampler", "stratified_bounces", "nee_all",
                                   "glossy_light_samples", "track", "gated", "links", "shadow_linked", "tri_recv",
                                   "light_vis", "light_recv", "light_shadow", "emit_vis",
                                   "emit_recv", "mat_refl", "defer_pdf", "probed", "caustic_light",
                                   "caustic_plain", "caustic_caster"])
# Ray visibility and light/shadow linking (scene/links.py; integrator.py builds the tables):
#   track         the lanes' ray types matter (the next ray's type is written: ``_lobe_class``)
#   gated         next-event estimation and emission found by BSDF sampling are filtered per
#                 light: its ray-type bits against the connection's class, its receiver mask
#                 against the vertex's receiver set (``_allowed``)
#   links         light linking: the receiver set of a vertex is its object's (``tri_recv``)
#   shadow_linked lights with shadow linking whose emission BSDF-sampled rays can hit (area,
#                 sphere, sun disk, …): found by a dedicated shadow ray that only their blockers
#                 stop (as Cycles' dedicated light rays), not at the closest surface
#   light_vis/light_recv/light_shadow   per light (the mesh light and the world: everything)
#   emit_vis/emit_recv  per emitter triangle of the mesh light (its object's)
#   mat_refl      per material: the class of a reflection (a layered stack: diffuse if one of
#                 its interfaces is diffuse, else glossy; transmission is always TRANSMIT)
# probed: per light, whether smooth glass and a coated kind's smooth top connect their mirror
# direction to it (``_probe_reflection``): the lights a ray can hit that do not fill the sphere
# (area, sphere and disk lights, suns); empty where none is, or where ray visibility or linking
# filters rays (a shadow ray would not see what the mirror ray sees).
# defer_pdf: a layered continuation's MIS pdf is estimated only if its ray finds a light that
# light sampling competes for (``_light_hit``), not for every continuation: its walks cost about a
# third of a layered vertex, and most continuations never need it (integrator.py decides).
# caustic_light: per light, whether light tracing takes its caustics (kernels/caustics.py);
# caustic_plain: per material, whether the photons understand it; caustic_caster: whether the
# photons pass through it (smooth glass and mirrors, sharp glossy kinds). All three empty where
# the scene's caustics are path traced only (backend/caustics.py says when).
# Ray-type bits (scene/links.py).
RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT = 1, 2, 4, 8
# Not a ray type: the ray continues a camera path that has met only mirrors and smooth glass, so
# the denoiser's albedo and normal are still to be written, at the first surface that is neither
# (as Cycles' denoising features follow specular bounces to what they show).
FEATURES_PENDING = 128
# Not ray types either: caustics that light tracing takes (kernels/caustics.py). CAUSTIC_FROM: the
# ray left the camera's hit on a plain material that is not a caster; CAUSTIC_CHAIN: it left a
# caster vertex (smooth glass, a mirror, a sharp glossy surface) of such a path. The emission of
# a covered light (``caustic_light``) that a CAUSTIC_CHAIN ray finds belongs to the photons: it
# is dropped here.
CAUSTIC_FROM = 16
CAUSTIC_CHAIN = 32
NO_RECEIVER = 64
NO_PARAMS = (0.0,) * 12      # km.bind's 12-tuple, for lanes that do not use it
_NO_DUV = (0.0,) * 6         # a layered lane's dP/du, dP/dv where its stack has no bump map
MAX_MIX_DEPTH = 4            # materials/mix.MAX_DEPTH: nested Mix / Add Shaders
ONE_MINUS_EPS = 1.0 - 2.0 ** -53
TABLE_NEE = 2                # light samples at a tabulated stack: this many times glossy_light_samples


@kernel
def _offset(p, ng, d):
    """p moved off the surface along ±ng, to the side d points to."""
    side = 1.0 if ng[0] * d[0] + ng[1] * d[1] + ng[2] * d[2] >= 0.0 else -1.0
    s = side * (OFFSET_ABSOLUTE + OFFSET_RELATIVE * max(abs(p[0]), max(abs(p[1]), abs(p[2]))))
    return (p[0] + s * ng[0], p[1] + s * ng[1], p[2] + s * ng[2])


@kernel
def _clamped(c, clamp, bounce):
    """Clamp Indirect as Cycles has it: light a path gathers at a vertex after the camera's hit
    (``bounce`` > 0: light samples taken there, emission found by the ray leaving it) is scaled
    down so that the sum of its RGB is at most ``clamp`` (off when ≤ 0). The camera hit's own
    light — its light samples and the emission its continuation finds — is direct light and
    never clamped; nor is what the camera sees."""
    if clamp > 0.0 and bounce > 0:
        m = c[0] + c[1] + c[2]
        if m > clamp:
            s = clamp / m
            return (c[0] * s, c[1] * s, c[2] * s)
    return c


@inlined
def _add(L, slot, c):
    L[slot, 0] += c[0]
    L[slot, 1] += c[1]
    L[slot, 2] += c[2]


# How the vertex a ray left from was lit (the queue's ``delta`` code): the MIS weight of a light
# the ray then hits depends on it.
VIA_SAMPLED = 0      # a non-delta BSDF sample; next-event estimation picked one light
VIA_DELTA = 1        # a delta lobe (or the camera): no light sampling competes
VIA_ALL_LIGHTS = 2   # a non-delta BSDF sample; next-event estimation sampled every light
VIA_SPLIT = 4        # (added to 0 or 2) next-event estimation took S.glossy_light_samples samples, not one
VIA_TABLE = 8        # (added to VIA_SPLIT) ... times TABLE_NEE (a tabulated stack)
VIA_PROBED = 16      # the mirror branch of smooth glass whose lights the vertex took already
VIA_TOP_PROBED = 32  # (added to the others) the sharp top's lobe of a coated kind, whose probed
                     # lights the vertex took already (``_probe_lobe``)

#: The vertex a ray left, as MIS against light sampling needs it: its position, the pdf the ray's
#: direction was sampled with (< 0: deferred, ``S.defer_pdf``) and how light sampling competed
#: there (VIA_*).
CameFrom = namedtuple("CameFrom", ["o", "pdf", "via"])
#: A light sample for next-event estimation (``_light_sample``): world direction, distance to the
#: light, radiance over the solid-angle pdf, that pdf, and whether the light is a delta.
LightSample = namedtuple("LightSample", ["wi", "dist", "value", "pdf", "is_delta"])
#: A sampled continuation: world direction, its z in the shading frame, weight f·cos/pdf, pdf
#: and the VIA_* code a light this ray hits will be weighed with.
Continuation = namedtuple("Continuation", ["d", "wo_z", "weight", "pdf", "via"])

# A ray's deferred MIS pdf (``S.defer_pdf``): one float64 row per queued ray, written where a
# layered continuation leaves its pdf for later (the queue's pdf is then −1).
DFR_STACK, DFR_UV, DFR_DUV, DFR_WI, DFR_WO = 0, 1, 3, 9, 12
DFR_COLUMNS = 15


@inlined
def _light_density(LT, S, li, pdf_light, via, o):
    """Light sampling's density for emission found by BSDF sampling from o: the light's
    selection probability × its pdf × the number of light samples (0: light sampling never
    produces this ray — a delta vertex, a light it does not sample)."""
    if via == VIA_DELTA or via == VIA_PROBED:
        return 0.0
    if via & VIA_ALL_LIGHTS:
        sel = 1.0 if LT.params[li, C_POWER] > 0.0 else 0.0
    else:
        sel = ld.select_prob(LT, o, li)
    if via & VIA_SPLIT:
        sel *= S.glossy_light_samples
    if via & VIA_TABLE:
        sel *= TABLE_NEE
    return sel * pdf_light


@inlined
def _light_hit(LT, S, li, pdf_light, came, c, bounce, i, sl, target, L, sh_c, queued, counts):
    """Emission ``c`` (throughput × radiance) found by BSDF sampling, weighted by MIS against
    light sampling from o (the power heuristic with sample counts; weight 1 where light
    sampling cannot produce the ray), clamped, added to L (``target`` −1) or written to shadow
    ray ``target``. Where the ray left a layered vertex whose pdf is deferred (< 0,
    ``S.defer_pdf``) and light sampling competes, it is queued instead (a row of PD, PC):
    ``shade`` estimates that pdf after its lane loop and weighs the queue then. ``came``: the
    vertex the ray left (CameFrom)."""
    o, prev_pdf, via = came
    PD, PC = queued
    if (via == VIA_PROBED or (via & VIA_TOP_PROBED) != 0) and S.probed[li]:
        # _probe_reflection or _probe_lobe counted this light already; a dedicated ray carries nothing
        _weighted_to(c, 0.0, S, bounce, sl, target, L, sh_c)
        return
    dl = _light_density(LT, S, li, pdf_light, via, o)
    if dl > 0.0 and prev_pdf < 0.0:
        k = counts[4]
        PD[k, 0] = i
        PD[k, 1] = target
        PC[k, 0], PC[k, 1], PC[k, 2] = c
        PC[k, 3] = dl
        counts[4] = k + 1
        return
    w = power_heuristic(prev_pdf, dl) if dl > 0.0 else 1.0
    _weighted_to(c, w, S, bounce, sl, target, L, sh_c)


@inlined
def _weighted_to(c, w, S, bounce, sl, target, L, sh_c):
    cc = _clamped((c[0] * w, c[1] * w, c[2] * w), S.clamp, bounce)
    if target >= 0:
        sh_c[target, 0], sh_c[target, 1], sh_c[target, 2] = cc
    else:
        _add(L, sl, cc)


@inlined
def _deferred_pdf(ST, TX, dfr, i, key, segment, walk):
    """The MIS pdf of the layered continuation lane i sampled at bounce ``segment``: its row of
    ``dfr`` holds the stack, (u, v), dP/du and dP/dv, wi and wo in the shading frame (DFR_*)."""
    r = dfr[i]
    _, p, _, _, _, _, _ = layered.shade_lane(
        ST, TX, int(r[DFR_STACK]), r[DFR_UV], r[DFR_UV + 1],
        (r[DFR_DUV], r[DFR_DUV + 1], r[DFR_DUV + 2], r[DFR_DUV + 3], r[DFR_DUV + 4], r[DFR_DUV + 5]),
        (r[DFR_WI], r[DFR_WI + 1], r[DFR_WI + 2]), (r[DFR_WO], r[DFR_WO + 1], r[DFR_WO + 2]),
        layered.LaneAsks(nee=False, nee_pdf=False, do_continue=False, sample_pdf=False, pdf_only=True,
                         camera=False), key, segment, walk)
    return p


@inlined
def _defer_row(row, sid, u, v, duv, wi, wo):
    row[DFR_STACK] = sid
    row[DFR_UV] = u
    row[DFR_UV + 1] = v
    for j in range(6):
        row[DFR_DUV + j] = duv[j]
    for j in range(3):
        row[DFR_WI + j] = wi[j]
        row[DFR_WO + j] = wo[j]


@inlined
def _interp3(rows, prim, c, b1, b2):
    """The 3-vector at columns c (corner 0), c + 3, c + 6 of a shading row, interpolated."""
    a0 = np.float64(rows[prim, c])
    a1 = np.float64(rows[prim, c + 1])
    a2 = np.float64(rows[prim, c + 2])
    return (a0 + b1 * (np.float64(rows[prim, c + 3]) - a0) + b2 * (np.float64(rows[prim, c + 6]) - a0),
            a1 + b1 * (np.float64(rows[prim, c + 4]) - a1) + b2 * (np.float64(rows[prim, c + 7]) - a1),
            a2 + b1 * (np.float64(rows[prim, c + 5]) - a2) + b2 * (np.float64(rows[prim, c + 8]) - a2))


@kernel
def _normalize(a):
    n = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    return (a[0] / n, a[1] / n, a[2] / n) if n > 0.0 else a


@kernel
def _valid_reflection_normal(wi, ns, ng):
    """Bend an interpolated shading normal so the mirror direction of wi stays above the
    geometric surface (the idea of Cycles' ensure_valid_specular_reflection, own derivation):
    on coarse smooth-shaded meshes the mirror about ns can point below the triangle, and that
    energy would be lost (dark rims on mirrors). There the reflection is lifted to just above
    the geometric plane (cosine ``threshold``) and ns replaced by the half vector of wi and the
    lifted reflection, on ns's side."""
    wi_ng = _dot(wi, ng)
    side = 1.0 if wi_ng >= 0.0 else -1.0
    c = _dot(wi, ns)
    r_ng = side * (2.0 * c * _dot(ns, ng) - wi_ng)
    threshold = min(0.9 * abs(wi_ng), 0.01)
    if not (r_ng < threshold and c * side > 0.0):
        return ns
    ngw = (ng[0] * side, ng[1] * side, ng[2] * side)
    r = (2.0 * c * ns[0] - wi[0], 2.0 * c * ns[1] - wi[1], 2.0 * c * ns[2] - wi[2])
    k = threshold - _dot(r, ngw)
    rb = _normalize((r[0] + k * ngw[0], r[1] + k * ngw[1], r[2] + k * ngw[2]))
    h = _normalize((wi[0] + rb[0], wi[1] + rb[1], wi[2] + rb[2]))
    sg = 1.0 if c > 0.0 else -1.0
    return (h[0] * sg, h[1] * sg, h[2] * sg)


@inlined
def _resolve_mix(MT, TX, m, u, v, r):
    """The component row of a Mix / Add Shader material that shades this hit, and the factor its
    contributions carry (materials/mix.py): a mix picks A with probability 1 − f and B with f
    (factor 1: the expectation is the mixture); an add picks each of its n components with
    probability 1/n (factor n: the expectation is the sum). r (uniform) is reused for nested
    mixes by stretching the chosen interval back to [0, 1)."""
    scale = 1.0
    for _ in range(MAX_MIX_DEPTH + 1):
        k = MT.kind[m]
        if k == km.MIX:
            f = min(max(km._scalar(MT, TX, m, km.MIX_FACTOR, u, v), 0.0), 1.0)
            if r < 1.0 - f:
                r = r / (1.0 - f)
                m = np.int32(MT.values[m, km.MIX_C0])
            else:
                r = (r - (1.0 - f)) / f if f > 0.0 else 0.0
                m = np.int32(MT.values[m, km.MIX_C0 + 1])
        elif k == km.ADD:
            n = int(MT.values[m, km.MIX_N])
            j = min(int(r * n), n - 1)
            r = r * n - j
            scale *= n
            m = np.int32(MT.values[m, km.MIX_C0 + j])
        else:
            break
        r = min(max(r, 0.0), ONE_MINUS_EPS)
    return m, scale


@inlined
def _mapped_normal(MT, TX, m, u, v, ns, tangent):
    """ns turned by material m's normal map (Blender's Normal Map node in tangent space): the
    map's vector (x, y, z) in the frame (UV tangent, n × tangent, ns), then mixed with ns by the
    strength k as Cycles does, normalize(ns + k·(mapped − ns)). Applied to the surface's own
    (front-side) normal before a back face is turned towards the viewer, as Cycles does."""
    c = km._rgb(MT, TX, m, km.N_MAP, u, v)
    if MT.nmode[m] == 2:                       # texture: RGB · 2 − 1, kept above the surface
        c = (2.0 * c[0] - 1.0, 2.0 * c[1] - 1.0, max(2.0 * c[2] - 1.0, 1e-3))
    s, t = _frame(ns, tangent)
    w = _normalize((c[0] * s[0] + c[1] * t[0] + c[2] * ns[0], c[0] * s[1] + c[1] * t[1] + c[2] * ns[1],
                    c[0] * s[2] + c[1] * t[2] + c[2] * ns[2]))
    k = MT.values[m, km.N_STRENGTH]
    if k != 1.0:
        w = _normalize((ns[0] + k * (w[0] - ns[0]), ns[1] + k * (w[1] - ns[1]), ns[2] + k * (w[2] - ns[2])))
    return w


@inlined
def _lerp_corner(A, k0, j, c, a):
    """Corner c (3 values at 3c) of moving triangle j between motion steps k0 and k0 + 1."""
    return (np.float64(A[k0, j, 3 * c]) + a * (np.float64(A[k0 + 1, j, 3 * c]) - np.float64(A[k0, j, 3 * c])),
            np.float64(A[k0, j, 3 * c + 1]) + a * (np.float64(A[k0 + 1, j, 3 * c + 1]) - np.float64(A[k0, j, 3 * c + 1])),
            np.float64(A[k0, j, 3 * c + 2]) + a * (np.float64(A[k0 + 1, j, 3 * c + 2]) - np.float64(A[k0, j, 3 * c + 2])))


@inlined
def _moving_surface(G, R, pr, tm, b1, b2):
    """(point, unit geometric normal (CCW), shading normal, UV tangent) of moving triangle pr at
    shutter time tm in [0, 1): its corners and normals interpolated linearly between the two
    motion steps around tm, as embree interpolates the vertices it traces (embree_lib.py)."""
    K = G.mv.shape[0]
    j = pr - G.moving_start
    x = tm * (K - 1)
    k0 = min(int(x), K - 2)
    a = x - k0
    c0 = _lerp_corner(G.mv, k0, j, 0, a)
    c1 = _lerp_corner(G.mv, k0, j, 1, a)
    c2 = _lerp_corner(G.mv, k0, j, 2, a)
    e1 = (c1[0] - c0[0], c1[1] - c0[1], c1[2] - c0[2])
    e2 = (c2[0] - c0[0], c2[1] - c0[1], c2[2] - c0[2])
    p = (c0[0] + b1 * e1[0] + b2 * e2[0], c0[1] + b1 * e1[1] + b2 * e2[1], c0[2] + b1 * e1[2] + b2 * e2[2])
    ng = _normalize(_cross(e1, e2))
    ns = ng
    if G.has_normals:
        n0 = _lerp_corner(G.mn, k0, j, 0, a)
        n1 = _lerp_corner(G.mn, k0, j, 1, a)
        n2 = _lerp_corner(G.mn, k0, j, 2, a)
        ns = _normalize((n0[0] + b1 * (n1[0] - n0[0]) + b2 * (n2[0] - n0[0]),
                         n0[1] + b1 * (n1[1] - n0[1]) + b2 * (n2[1] - n0[1]),
                         n0[2] + b1 * (n1[2] - n0[2]) + b2 * (n2[2] - n0[2])))
    tan = (0.0, 0.0, 0.0)
    if G.has_uvs:
        # dP/du from the UV differences (as kernels/soup.py's frames).
        u0, w0 = np.float64(R[pr, ROW_UV]), np.float64(R[pr, ROW_UV + 1])
        dpdu, _, ok = _bump.uv_derivatives(e1, e2, np.float64(R[pr, ROW_UV + 2]) - u0, np.float64(R[pr, ROW_UV + 3]) - w0,
                                           np.float64(R[pr, ROW_UV + 4]) - u0, np.float64(R[pr, ROW_UV + 5]) - w0)
        if ok:
            tan = _normalize(dpdu)
    return p, ng, ns, tan


@inlined
def facing_viewer(wi, ng, ns):
    """A two-sided (reflection-only) material is seen from both sides: its normals turned
    towards the viewer wi; where the shading normal still faces away, the geometric one."""
    if _dot(wi, ng) < 0.0:
        ng = (-ng[0], -ng[1], -ng[2])
        ns = (-ns[0], -ns[1], -ns[2])
    if _dot(wi, ns) <= 0.0:
        ns = ng
    return ng, ns


@inlined
def static_surface(G, R, pr, b1, b2):
    """(point, geometric normal, unit shading normal, UV tangent) of a hit on a triangle that
    does not move, from its barycentrics (the normal interpolated where the mesh has normals)."""
    p = _interp3(R, pr, ROW_V, b1, b2)
    ng = (np.float64(R[pr, ROW_NG]), np.float64(R[pr, ROW_NG + 1]), np.float64(R[pr, ROW_NG + 2]))
    if G.has_normals:
        ns = _interp3(R, pr, ROW_N, b1, b2)
        ln = math.sqrt(_dot(ns, ns))
        ns = (ns[0] / ln, ns[1] / ln, ns[2] / ln) if ln > 0.0 else ng
    else:
        ns = ng
    tan = (np.float64(R[pr, ROW_TAN]), np.float64(R[pr, ROW_TAN + 1]), np.float64(R[pr, ROW_TAN + 2]))
    return p, ng, ns, tan


@inlined
def surface_uv(G, R, pr, b1, b2):
    """The hit's texture coordinates (0, 0 without UVs)."""
    if not G.has_uvs:
        return 0.0, 0.0
    u0 = np.float64(R[pr, ROW_UV])
    v0 = np.float64(R[pr, ROW_UV + 1])
    return (u0 + b1 * (np.float64(R[pr, ROW_UV + 2]) - u0) + b2 * (np.float64(R[pr, ROW_UV + 4]) - u0),
            v0 + b1 * (np.float64(R[pr, ROW_UV + 3]) - v0) + b2 * (np.float64(R[pr, ROW_UV + 5]) - v0))


@inlined
def _uv_derivatives(R, pr):
    """(dP/du, dP/dv, ok) of triangle pr from its corners and UVs (kernels/bump.py)."""
    x0, y0, z0 = np.float64(R[pr, ROW_V]), np.float64(R[pr, ROW_V + 1]), np.float64(R[pr, ROW_V + 2])
    e1 = (np.float64(R[pr, ROW_V + 3]) - x0, np.float64(R[pr, ROW_V + 4]) - y0, np.float64(R[pr, ROW_V + 5]) - z0)
    e2 = (np.float64(R[pr, ROW_V + 6]) - x0, np.float64(R[pr, ROW_V + 7]) - y0, np.float64(R[pr, ROW_V + 8]) - z0)
    u0, v0 = np.float64(R[pr, ROW_UV]), np.float64(R[pr, ROW_UV + 1])
    return _bump.uv_derivatives(e1, e2, np.float64(R[pr, ROW_UV + 2]) - u0, np.float64(R[pr, ROW_UV + 3]) - v0,
                                np.float64(R[pr, ROW_UV + 4]) - u0, np.float64(R[pr, ROW_UV + 5]) - v0)


@inlined
def _bumped_normal(MT, TX, R, pr, m, u, v, ns, side):
    """ns tilted by material m's bump map (Blender's Bump node, kernels/bump.py): the height
    texture's gradient through the triangle's UV map, times the distance (the height slot's
    factor), mixed by the strength. ``side`` −1 on a back face: seen from below a bump is a dent
    (Cycles bumps the normal it has turned towards the viewer)."""
    dpdu, dpdv, ok = _uv_derivatives(R, pr)
    if not ok:
        return ns                              # no UV map on this triangle: no gradient
    gu, gv = lookup_gradient(TX, MT.tex[m, km.B_HEIGHT], u, v)
    return _bump.tilt(ns, dpdu, dpdv, gu, gv, side * MT.values[m, km.B_HEIGHT], MT.values[m, km.B_STRENGTH])


@inlined
def _local_uv_derivatives(R, pr, fs, ft, ns):
    """dP/du and dP/dv of triangle pr in the lane's shading frame, for the bump maps of a
    layered stack's interfaces (zeros without a UV map: the interfaces stay unbumped)."""
    dpdu, dpdv, ok = _uv_derivatives(R, pr)
    if not ok:
        return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    a = _local(fs, ft, ns, dpdu)
    b = _local(fs, ft, ns, dpdv)
    return (a[0], a[1], a[2], b[0], b[1], b[2])


@kernel
def _lane_pixel_sample(i, spp, inv_spp):
    """(i // spp, i % spp) for 0 ≤ i < 2^52 without a 64-bit integer division (~40 cycles):
    the float quotient is off by at most one, and the remainder tells which way."""
    q = int(i * inv_spp)
    r = i - q * spp
    if r < 0:
        q -= 1
        r += spp
    elif r >= spp:
        q += 1
        r -= spp
    return q, r


@inlined
def _linked(mask, rs):
    """Light linking: does an emitter with receiver mask ``mask`` light receiver set ``rs``?"""
    return rs >= NO_RECEIVER or ((mask >> np.int64(rs)) & 1) != 0


@inlined
def _lobe_class(S, kind, m, reflect):
    """The ray type of a direction a material scatters into (Cycles' labels): reflection by a
    diffuse material is diffuse, by a conductor or dielectric glossy (mirrors included), by a
    layered stack ``mat_refl``; every transmission is transmission."""
    if not reflect:
        return RAY_TRANSMIT
    if kind == km.DIFFUSE:
        return RAY_DIFFUSE
    if km.is_stack(kind):
        return S.mat_refl[m]
    return RAY_GLOSSY


@inlined
def _allowed(S, li, tri, rs, cls):
    """May light li (emitter triangle tri of the mesh light) light this vertex (receiver set
    rs) through a connection of class cls? (Cycles' SHADER_EXCLUDE_* and light sets.)"""
    if li == S.mesh_light:
        if tri < 0:
            return True
        return (S.emit_vis[tri] & cls) != 0 and _linked(S.emit_recv[tri], rs)
    return (S.light_vis[li] & cls) != 0 and _linked(S.light_recv[li], rs)


@inlined
def _light_sample(S, LT, TX, li, p, u0, u1, fs, ft, ns, ng):
    """A next-event sample of light li from p: (wi world, dist, value, pdf, is_delta, wi in the
    shading frame, live = it carries light and lies on the same side for both normals, the
    mesh light's emitter triangle or −1)."""
    tri = -1
    if S.gated and li == S.mesh_light:
        wi_w, dist, value, lpdf, tri = _mesh.sample_tri(LT.iparams, li, LT.aux, LT.iaux, TX, p, u0, u1)
        is_delta = False
    else:
        wi_w, dist, value, lpdf, is_delta = ld.sample(LT, TX, li, p, u0, u1)
    wo_n = _local(fs, ft, ns, wi_w)
    live = max(value[0], max(value[1], value[2])) > 0.0 and _dot(wi_w, ng) * wo_n[2] > 0.0
    return wi_w, dist, value, lpdf, is_delta, wo_n, live, tri


@inlined
def _push_shadow(S, bounce, slot, p, ng, wi_w, dist, c, mask, shadows, counts):
    """A shadow ray from p (offset) towards wi_w over dist, carrying c if nothing blocks it;
    ``mask``: the blocker sets that stop it (shadow linking; −1: all)."""
    _push_ray(S, bounce, slot, _offset(p, ng, wi_w), wi_w, dist, c, mask, shadows, counts)


@inlined
def _push_ray(S, bounce, slot, origin, wi_w, dist, c, mask, shadows, counts):
    """Append a shadow ray to ``shadows`` (kernels/workitems.py ShadowRays)."""
    k = counts[1]
    shadows.slot[k] = slot
    shadows.mask[k] = mask
    for j in range(3):
        shadows.o32[k, j] = origin[j]
        shadows.d32[k, j] = wi_w[j]
    shadows.t32[k] = min(dist * (1.0 - SHADOW_EPS), 3e38) if math.isfinite(dist) else 3e38
    cc = _clamped(c, S.clamp, bounce)
    shadows.c[k, 0], shadows.c[k, 1], shadows.c[k, 2] = cc
    counts[1] = k + 1


@inlined
def _nee(S, bounce, slot, beta, p, ng, ls, sel_p, f, bsdf_pdf, mask, shadows, counts):
    """Light-sample contribution of ``ls`` (a LightSample): MIS (power heuristic) against BSDF
    sampling, divided by the selection probability; a shadow ray if it carries anything."""
    wi_w, dist, value, lpdf, is_delta = ls
    w = 1.0 if is_delta else power_heuristic(sel_p * lpdf, bsdf_pdf)
    w /= sel_p
    c = (w * beta[0] * f[0] * value[0], w * beta[1] * f[1] * value[1], w * beta[2] * f[2] * value[2])
    if max(c[0], max(c[1], c[2])) > 0.0:
        _push_shadow(S, bounce, slot, p, ng, wi_w, dist, c, mask, shadows, counts)


@inlined
def _met_light(LT, li, origin, r):
    """Light ``li`` as a ray from ``origin`` along ``r`` would meet it, lights being transparent:
    (its distance, INF for one at infinity; its radiance there, 0 where the ray misses it; the
    density light sampling has for that ray, per solid angle)."""
    if LT.is_infinite[li]:
        return INF, ld.eval_escaped(LT, li, r), ld.pdf_escaped(LT, li, r)
    dist = ld.intersect(LT, li, origin, r, INF)
    if not dist < INF:
        return INF, (0.0, 0.0, 0.0), 0.0
    return dist, ld.eval_hit(LT, li, origin, r, dist), ld.pdf_hit(LT, li, origin, r, dist)


@inlined
def _probe_reflection(S, LT, bounce, slot, beta, p, ng, r, refl, shadows, counts):
    """The lights seen in the mirror direction ``r`` of smooth glass (or a coated kind's smooth
    top, sampled with probability ≥ 20 % at weight F/that), reflectance ``refl``: one
    shadow ray per light that direction meets, carrying beta · refl · its radiance. Sampling
    chooses the mirror with probability refl only, so at glass (refl ≈ 4 %) the lights seen by
    reflection — a sun or a lamp mirrored in a window or a sphere — came in as a few samples
    worth 25× the light; here every sample takes them at their mean. The mirror branch, when
    chosen, then counts none of these lights (VIA_PROBED: ``_light_hit`` weighs them 0). Only
    lights much brighter than what the glass refracts gain (``S.probed``): for a world that is
    about as bright in every direction the Fresnel choice is already the right one, and taking it
    at every sample adds the choice's noise (a glass ball in a constant world: exact with the
    choice alone); emitting surfaces (the mesh light) stay with the mirror ray too. Lights are
    transparent to rays (as in Cycles), so a light the shadow ray reaches is exactly one the mirror
    ray would have passed or escaped to."""
    origin = _offset(p, ng, r)             # where the mirror ray would start
    for li in range(S.probed.shape[0]):
        if not S.probed[li]:
            continue
        dist, le, _ = _met_light(LT, li, origin, r)
        if le[0] > 0.0 or le[1] > 0.0 or le[2] > 0.0:
            c = (beta[0] * refl * le[0], beta[1] * refl * le[1], beta[2] * refl * le[2])
            # clamped as the mirror ray's emission would be: light gathered at this vertex
            _push_ray(S, bounce, slot, origin, r, dist, c, -1, shadows, counts)


@inlined
def _probe_lobe(S, LT, bounce, slot, beta, p, ng, r, weight, pdf, via, shadows, counts):
    """The lights seen along ``r``, a direction drawn from the sharp top's lobe alone of a coated
    kind (kernels/materials.py ``sharp_top``), at every sample: the generalisation of
    ``_probe_reflection`` to a top that is rough but sharp (α ≤ SHARP_ALPHA: a clear coat, glossy
    plastic, car paint). The sampler takes that lobe with probability w_s only (≥ 20 %) and so
    found a sun mirrored in the coat in one sample in five, at five times its value — the
    highlight's noise, now direct light that Clamp Indirect does not touch. Here each light the
    direction meets carries beta · (f/pdf)(r) · w_s (``weight``) · its radiance, weighted against
    light sampling by the power heuristic as the continuation's hit would be (``pdf``: the
    sampler's whole pdf at r; ``via``: how light sampling competed here); the continuation, when
    it takes the top's lobe, then counts none of these lights (VIA_TOP_PROBED). Unbiased: the
    lobe's part of the BSDF strategy, ∫ f L w_s p_top / pdf, is estimated with samples of p_top
    instead of with the w_s-chance of one, and the body's part is the continuation's as before.
    At the camera's hit only: deeper, a highlight's noise is spread over the path's other
    choices (the presets scene, 80², 16 spp, 8 seeds: image variance 29.99 probed at the camera's
    hit, 30.45 at every vertex, whose shadow rays cost 3–8 % more CPU; 68.8 without)."""
    origin = _offset(p, ng, r)             # where the continuation would start
    for li in range(S.probed.shape[0]):
        if not S.probed[li]:
            continue
        dist, le, pdf_l = _met_light(LT, li, origin, r)
        if le[0] > 0.0 or le[1] > 0.0 or le[2] > 0.0:
            dl = _light_density(LT, S, li, pdf_l, via, origin)
            w = power_heuristic(pdf, dl) if dl > 0.0 else 1.0
            c = (beta[0] * weight[0] * w * le[0], beta[1] * weight[1] * w * le[1], beta[2] * weight[2] * w * le[2])
            _push_ray(S, bounce, slot, origin, r, dist, c, -1, shadows, counts)


@inlined
def _roulette(MT, TX, m, u, v, wi, ng, beta):
    """Survival probability of a path at a surface it reached at depth ≥ ``rr_depth``:
    min(1, √(max throughput · s)) (Cycles' √, with s below). Decided *after* the emission that
    ray found (lights it passed, the surface's own), before next-event estimation and the
    continuation, so emitters hit by BSDF sampling never carry roulette noise; survivors are
    divided by the probability, so any s > 0 keeps the estimate unbiased.

    s undoes the radiance compression of refraction (pbrt-v4's ``etaScale``, stateless here):
    Lamina's BTDF carries 1/η² into a denser medium, so a path inside glass has its throughput
    2.25× lower (η 1.5) only because of that convention, not because it carries less light; at a
    dielectric hit from inside (the back of its geometric normal) s = η², elsewhere 1. Measured
    on the peer Cornell box (rough-glass sphere; 64 spp, 8 seeds, variance of an image): 1353
    with min(1, max throughput) decided before tracing, 895 with the √, 861 decided after the
    emission, 640 with s; 470 with no roulette; Cycles 648. Without the glass sphere both
    renderers are at 142–163: the roulette noise was the glass's."""
    s = 1.0
    if MT.kind[m] == km.DIELECTRIC and _dot(wi, ng) < 0.0:
        eta = km._scalar(MT, TX, m, km.D_ETA, u, v)
        s = eta * eta
    return min(math.sqrt(max(beta[0], max(beta[1], beta[2])) * s), 1.0)


@inlined
def _continue(S, segment, slot, key, beta, p, ng, cont, rtype, recv, nxt, counts):
    """The next ray ``cont`` (a Continuation): leak guard, compaction into the next-ray queue
    ``nxt`` (a RayQueue; Russian roulette is decided at the surface the ray reaches,
    ``_roulette``)."""
    d_world, wo_z, weight, pdf, via = cont
    # The sampled side must agree for the shading and the geometric normal.
    if not (_dot(d_world, ng) * wo_z > 0.0):
        return
    b = (beta[0] * weight[0], beta[1] * weight[1], beta[2] * weight[2])
    peak = max(b[0], max(b[1], b[2]))
    if not math.isfinite(peak):
        counts[3] += 1
        return
    if not peak > 0.0:
        return
    k = counts[0]
    origin = _offset(p, ng, d_world)
    nxt.slot[k] = slot
    nxt.key[k] = key
    for j in range(3):
        nxt.o[k, j] = origin[j]
        nxt.d[k, j] = d_world[j]
        nxt.o32[k, j] = origin[j]
        nxt.d32[k, j] = d_world[j]
        nxt.beta[k, j] = b[j]
    nxt.pdf[k] = pdf
    nxt.delta[k] = via
    nxt.rtype[k] = rtype
    nxt.recv[k] = recv
    counts[0] = k + 1


@inlined
def _write_passes(PS, aux, sl, p, ng, ns, wi, u, v, has_uvs, m, pr):
    """The data passes of a camera ray's first hit (backend/passes.py: Cycles' conventions).
    Columns < 0 are passes nobody asked for."""
    rel = (p[0] - PS.cam_pos[0], p[1] - PS.cam_pos[1], p[2] - PS.cam_pos[2])
    along = _dot(rel, PS.cam_axis)          # distance along the view axis [m]
    if PS.depth >= 0:
        aux[sl, PS.depth] = along
    if PS.object_index >= 0:
        aux[sl, PS.object_index] = PS.object_pass[PS.tri_object[pr]]
    if PS.material_index >= 0:
        aux[sl, PS.material_index] = PS.material_pass[m]
    if PS.mist >= 0:
        dist = abs(along) if PS.ortho else math.sqrt(_dot(rel, rel))
        x = min(max((dist - PS.mist_start) * PS.mist_inv_depth, 0.0), 1.0)
        if PS.mist_falloff == 2.0:
            x = x * x
        elif PS.mist_falloff == 0.5:
            x = math.sqrt(x)
        elif PS.mist_falloff != 1.0:
            x = x ** PS.mist_falloff
        aux[sl, PS.mist] = x
    if PS.normal >= 0:
        # The shading normal on the camera's side of the surface (Cycles turns N towards the
        # incoming ray on back faces, whatever the material).
        side = 1.0 if _dot(wi, ng) >= 0.0 else -1.0
        aux[sl, PS.normal] = side * ns[0]
        aux[sl, PS.normal + 1] = side * ns[1]
        aux[sl, PS.normal + 2] = side * ns[2]
    if PS.position >= 0:
        aux[sl, PS.position] = p[0] + PS.origin[0]
        aux[sl, PS.position + 1] = p[1] + PS.origin[1]
        aux[sl, PS.position + 2] = p[2] + PS.origin[2]
    if PS.uv >= 0 and has_uvs and PS.object_uv[PS.tri_object[pr]]:
        aux[sl, PS.uv] = u
        aux[sl, PS.uv + 1] = v
        aux[sl, PS.uv + 2] = 1.0            # UV's third channel: this sample hit a UV map


@kernel(nogil=True)
def shade(tables, segment, lanes, cur, hits, film, nxt, shadows, walk, queued, counts):
    """One bounce for every traced lane (see the module docstring), with the named bundles of
    kernels/workitems.py: ``tables`` (SceneTables), ``lanes`` (Lanes: lane slot ``sl`` is sample
    ``sample0 + sl % spp`` of pixel ``pixels[sl // spp]``, for the path sampler), ``cur`` (the
    traced rays: a RayQueue of the active lanes) and ``hits`` (TracedHits) in; ``film``
    (FilmColumns), ``nxt`` (the next rays: a RayQueue), ``shadows`` (ShadowRays), ``walk``
    (WalkScratch) and ``queued`` (QueuedEmission) out. ``counts`` (int64[5]) gets [next rays,
    shadow rays, layered lanes, non-finite paths killed, deferred layered pdfs estimated].
    The data passes' table and columns (``tables.passes``, ``film.aux``: backend/passes.py) are
    untouched when ``PS.active`` is false; the shutter times are read only for moving triangles
    (``G.moving_start`` …). A ray's type and the receiver set of the vertex it left drive ray
    visibility and light linking (``Settings``); ``shadows.mask``: each shadow ray's blocker
    sets. The deferred MIS pdfs need one row only without layered stacks; the queued emission
    has room for the lanes × the lights a ray can find with light sampling competing
    (``S.defer_pdf`` only)."""
    G, MT, TX, LT, S, PS, ST = tables
    pixels, spp, sample0, lane_time = lanes
    slot, key, o, d, beta = cur.slot, cur.key, cur.o, cur.d, cur.beta
    prev_pdf, prev_delta, rtype, recv, dfr = cur.pdf, cur.delta, cur.rtype, cur.recv, cur.dfr
    tmax32, prim, t32, b1_32, b2_32 = hits
    L, albedo, normal, alpha, aux = film
    sh_c = shadows.c
    PD, PC = queued
    camera = segment == 0
    # The bounce, for Clamp Indirect (``_clamped``), of the vertex this segment's rays left: the
    # light they find belongs to it (−1: the camera); light samples taken here belong to this one.
    found = segment - 1
    inv_spp = 1.0 / spp
    last = segment == S.max_segments - 1
    can_nee = S.has_lights and segment + 1 < S.max_segments
    nh = S.hittable.shape[0]
    ni = S.infinite.shape[0]
    nsl = S.shadow_linked.shape[0] if not camera else 0
    gate_hits = S.gated and not camera     # camera rays see every light (Cycles)
    caustics = S.caustic_light.shape[0] > 0
    for i in range(slot.shape[0]):
        sl = slot[i]
        rt = rtype[i]
        # a caustic path the photons take: its covered lights carry nothing here
        chain = caustics and (rt & CAUSTIC_CHAIN) != 0
        rv = recv[i]
        ro = (o[i, 0], o[i, 1], o[i, 2])
        rd = (d[i, 0], d[i, 1], d[i, 2])
        bt = (beta[i, 0], beta[i, 1], beta[i, 2])
        came = CameFrom(ro, prev_pdf[i], prev_delta[i])
        pr = prim[i]
        t_surf = np.float64(t32[i]) if pr >= 0 else INF
        t_limit = min(t_surf, np.float64(tmax32[i]))
        # 0. lights with shadow linking: what this ray would see of them past surfaces that do
        # not block them goes to a dedicated shadow ray along the ray (only their blockers stop
        # it); the loops below then skip them.
        for j in range(nsl):
            li = S.shadow_linked[j]
            if not ((S.light_vis[li] & rt) != 0 and _linked(S.light_recv[li], rv)):
                continue
            if LT.is_infinite[li]:
                le = ld.eval_escaped(LT, li, rd)
                pdf_l = ld.pdf_escaped(LT, li, rd)
                tl = INF
            else:
                tl = ld.intersect(LT, li, ro, rd, INF)
                if not tl < INF:
                    continue
                le = ld.eval_hit(LT, li, ro, rd, tl)
                pdf_l = ld.pdf_hit(LT, li, ro, rd, tl)
            if le[0] > 0.0 or le[1] > 0.0 or le[2] > 0.0:
                c = (bt[0] * le[0], bt[1] * le[1], bt[2] * le[2])
                k = counts[1]
                _push_ray(S, found, sl, ro, rd, tl, c, S.light_shadow[li], shadows, counts)
                _light_hit(LT, S, li, pdf_l, came, c, found, i, sl, k, L, sh_c, queued, counts)
        # 1. lights passed on the way (transparent, as in Cycles)
        for j in range(nh):
            li = S.hittable[j]
            if camera and not S.visible_camera[li]:
                continue
            if gate_hits and not ((S.light_vis[li] & rt) != 0 and _linked(S.light_recv[li], rv)
                                  and S.light_shadow[li] == -1):
                continue
            if chain and S.caustic_light[li]:
                continue
            tl = ld.intersect(LT, li, ro, rd, t_limit)
            if tl < INF:
                le = ld.eval_hit(LT, li, ro, rd, tl)
                _light_hit(LT, S, li, ld.pdf_hit(LT, li, ro, rd, tl), came,
                           (bt[0] * le[0], bt[1] * le[1], bt[2] * le[2]), found, i, sl, -1, L, sh_c, queued,
                           counts)
        if pr < 0:
            if not (camera and S.transparent):
                for j in range(ni):
                    li = S.infinite[j]
                    if camera and not S.visible_camera[li]:
                        continue
                    if gate_hits and not ((S.light_vis[li] & rt) != 0 and _linked(S.light_recv[li], rv)
                                          and S.light_shadow[li] == -1):
                        continue
                    if chain and S.caustic_light[li]:
                        continue
                    le = ld.eval_escaped(LT, li, rd)
                    if le[0] > 0.0 or le[1] > 0.0 or le[2] > 0.0:
                        _light_hit(LT, S, li, ld.pdf_escaped(LT, li, rd), came,
                                   (bt[0] * le[0], bt[1] * le[1], bt[2] * le[2]), found, i, sl, -1, L, sh_c,
                                   queued, counts)
            continue
        if camera:
            # Holdouts are black, transparent holes for camera rays (as in Cycles); they still
            # cast shadows and show in reflections.
            if G.holdout[pr]:
                continue
            alpha[sl] = 1.0
        # 2. the surface, in float64 from barycentrics (accurate to the vertex precision)
        b1 = np.float64(b1_32[i])
        b2 = np.float64(b2_32[i])
        R = G.rows
        if pr >= G.moving_start:
            p, ng, ns, tan = _moving_surface(G, R, pr, np.float64(lane_time[sl]), b1, b2)
        else:
            p, ng, ns, tan = static_surface(G, R, pr, b1, b2)
        u, v = surface_uv(G, R, pr, b1, b2)
        m = G.irows[pr, ROW_MAT]
        m_surface = m                 # the object's material (passes); m: the one that shades
        if km.is_mix(MT.kind[m]):
            m, mix_scale = _resolve_mix(MT, TX, m, u, v, uniform(key[i], bounce_dim(segment, SLOT_MIX)))
            bt = (bt[0] * mix_scale, bt[1] * mix_scale, bt[2] * mix_scale)
        wi = (-rd[0], -rd[1], -rd[2])
        mapped = MT.nmode[m] != 0
        if mapped:
            ns = _mapped_normal(MT, TX, m, u, v, ns, tan)
        if MT.bump[m] and G.has_uvs:           # on top of the normal map (Bump node's Normal input)
            ns = _bumped_normal(MT, TX, R, pr, m, u, v, ns, 1.0 if _dot(wi, ng) >= 0.0 else -1.0)
            mapped = True
        if camera and PS.active:
            _write_passes(PS, aux, sl, p, ng, ns, wi, u, v, G.has_uvs, m_surface, pr)
        # Both faces emit (as Cycles' emission shader), or the front only (emission_sides).
        if MT.emits[m] and (not MT.emit_front[m] or _dot(wi, ng) > 0.0) and not (
                gate_hits and S.links and G.irows[pr, ROW_EMIT] >= 0
                and not _linked(S.emit_recv[G.irows[pr, ROW_EMIT]], rv)):
            le = km.emission(MT, TX, m, u, v)
            c = (bt[0] * le[0], bt[1] * le[1], bt[2] * le[2])
            if chain and S.mesh_light >= 0 and S.caustic_light[S.mesh_light]:
                pass                           # a caustic path the photons take
            elif S.mesh_light >= 0:
                local = G.irows[pr, ROW_EMIT]
                pdf_l = ld.mesh_pdf_hit(LT, S.mesh_light, ro, rd, t_surf, local) if local >= 0 else 0.0
                _light_hit(LT, S, S.mesh_light, pdf_l, came, c, found, i, sl, -1, L, sh_c, queued, counts)
            else:
                _weighted_to(c, 1.0, S, found, sl, -1, L, sh_c)
        # Russian roulette at this surface, after the emission the ray found (see _roulette)
        if segment >= S.rr_depth and not last:
            q = _roulette(MT, TX, m, u, v, wi, ng, bt)
            if not uniform(key[i], bounce_dim(segment - 1, SLOT_RR)) < q:
                continue
            bt = (bt[0] / q, bt[1] / q, bt[2] / q)
        # 3. shading frame and AOVs
        # The denoiser's features (albedo, normal) at the camera's hit and, behind mirrors and
        # smooth glass, again at the first other surface (FEATURES_PENDING), which overwrites
        # them; the albedo times the throughput of the specular chain (1 at the camera's hit).
        features = camera or (rt & FEATURES_PENDING) != 0
        if features:
            # The denoiser's normal, like the Normal pass: turned towards the camera on back
            # faces (Cycles flips N there, whatever the material).
            facing = 1.0 if _dot(wi, ng) >= 0.0 else -1.0
            normal[sl, 0], normal[sl, 1], normal[sl, 2] = facing * ns[0], facing * ns[1], facing * ns[2]
        kind = MT.kind[m]
        if MT.two_sided[m]:
            ng, ns = facing_viewer(wi, ng, ns)
        bent = False
        if G.has_normals or mapped:
            nv = _valid_reflection_normal(wi, ns, ng)
            # a bent normal depends on the view direction: a vertex bent here cannot be retraced
            # from the light, so its path stays the path tracer's (kernels/caustics.py)
            bent = nv[0] != ns[0] or nv[1] != ns[1] or nv[2] != ns[2]
            ns = nv
        # A caster vertex of a caustic path the photons take (kernels/caustics.py): its light
        # samples of the covered lights, its mirror probe and the covered lights its
        # continuation finds are theirs.
        in_chain = (caustics and (rt & (CAUSTIC_FROM | CAUSTIC_CHAIN)) != 0 and S.caustic_caster[m_surface]
                    and not bent)
        fs, ft = _frame(ns, tan)
        wi_l = _local(fs, ft, ns, wi)
        # 4a. light sample (shared with layered lanes) from the sampler's 2-D slots of this bounce.
        # Stratified numbers for the first bounces, where they pay (direct light at the first
        # hits); hashed ones deeper, where stratification no longer shows but costs ~40 ns/slot.
        smode = S.sampler if segment < S.stratified_bounces else 1
        smp = 0
        ps = np.uint64(0)
        if smode == 0:
            q, j = _lane_pixel_sample(sl, spp, inv_spp)
            smp = sample0 + j
            ps = pixel_seed(S.seed, pixels[q])
        u_pick, u_lobe = get2(smode, ps, key[i], smp, bounce_dim(segment, SLOT_LIGHT_PICK))
        li = -1
        sel_p = 0.0
        wi_w = (0.0, 0.0, 1.0)
        dist = 0.0
        value = (0.0, 0.0, 0.0)
        lpdf = 0.0
        is_delta = True
        live = False
        wo_n = (0.0, 0.0, 1.0)
        # The receiver set of this vertex (light linking).
        rs = np.int64(S.tri_recv[pr]) if S.links else np.int64(NO_RECEIVER)
        # Few lights (S.nee_all = their number, 2-4): every one is sampled at an analytic
        # material's vertex (one shadow ray each) instead of picking one; layered stacks connect
        # to one picked light (their walks serve one direction).
        all_lights = can_nee and S.nee_all > 0 and kind != km.LAYERED
        # An analytic material's lane parameters; a delta-only one (smooth glass or mirror) takes
        # no light sample: nothing could use it.
        if kind != km.LAYERED:
            prm = km.bind(MT, TX, m, u, v)
            delta_only = km.is_delta_only(kind, prm)
        else:
            prm = NO_PARAMS
            delta_only = False
        if can_nee and not all_lights and not delta_only:
            li, sel_p = ld.select(LT, p, u_pick)
            if li >= 0 and sel_p > 0.0:
                ul0, ul1 = get2(smode, ps, key[i], smp, bounce_dim(segment, SLOT_LIGHT))
                wi_w, dist, value, lpdf, is_delta, wo_n, live, etri = _light_sample(
                    S, LT, TX, li, p, ul0, ul1, fs, ft, ns, ng)
                if live and S.gated:
                    live = _allowed(S, li, etri, rs, _lobe_class(S, kind, m, wi_l[2] * wo_n[2] > 0.0))
                if live and in_chain and S.caustic_light[li]:
                    live = False
        if kind == km.LAYERED:
            # 4b + 5 for a layered stack: one per-lane call (shared walks).
            counts[2] += 1
            sid = int(MT.values[m, km.LAYER_ID])
            duv = _NO_DUV
            if ST.head[sid, H_BUMP] != 0.0:
                duv = _local_uv_derivatives(R, pr, fs, ft, ns)
            f, bpdf, wo, weight, spdf, sdelta, alb = layered.shade_lane(
                ST, TX, sid, u, v, duv, wi_l, wo_n,
                layered.LaneAsks(nee=live, nee_pdf=not is_delta, do_continue=not last,
                                 sample_pdf=not S.defer_pdf, pdf_only=False, camera=camera),
                key[i], segment, walk)
            if camera:
                albedo[sl, 0], albedo[sl, 1], albedo[sl, 2] = alb
            elif features and wi_l[2] * wo[2] > 0.0:
                # behind a mirror or glass: the continuation's reflected weight, as shade_lane's
                # albedo estimate at a camera hit
                albedo[sl, 0], albedo[sl, 1], albedo[sl, 2] = bt[0] * weight[0], bt[1] * weight[1], bt[2] * weight[2]
            if live:
                _nee(S, segment, sl, bt, p, ng, LightSample(wi_w, dist, value, lpdf, is_delta), sel_p, f, bpdf,
                     S.light_shadow[li], shadows, counts)
            if not last and (weight[0] > 0.0 or weight[1] > 0.0 or weight[2] > 0.0):
                nrt = _lobe_class(S, kind, m, wi_l[2] * wo[2] > 0.0) if S.track else 0
                k0 = counts[0]
                _continue(S, segment, sl, key[i], bt, p, ng,
                          Continuation(_world(fs, ft, ns, wo), wo[2], weight, spdf,
                                       VIA_DELTA if sdelta else VIA_SAMPLED), nrt, rs, nxt, counts)
                if spdf < 0.0 and counts[0] > k0:
                    _defer_row(nxt.dfr[k0], sid, u, v, duv, wi_l, wo)
            continue
        dist_code = MT.dist[m]
        mask_code = MT.masking[m]
        if features:
            a = km.albedo(MT.tables, kind, prm, wi_l)
            albedo[sl, 0], albedo[sl, 1], albedo[sl, 2] = bt[0] * a[0], bt[1] * a[1], bt[2] * a[2]
        # 4b. next-event estimation. At a rough conductor light sampling is the noisy strategy
        # (its glossy lobe weighs the light's points very unequally): S.glossy_light_samples samples there,
        # each weighted 1/S.glossy_light_samples. Measured (docs/scene-format.md): 2 samples cut the IES
        # room's variance at equal samples 1497 -> 1194 for +2 % CPU, the grazing strips' 72 -> 62;
        # rough dielectrics gained nothing (their light samples mostly end inside the object).
        # Tabulated stacks whose top is not nearly a mirror take TABLE_NEE times as many: their
        # eval is cheap (0.3–0.6 µs) and their lobes glossy (Guo's Fig. 2 stack on a sphere under a
        # 5° sun, 64², 32 spp, 6 seeds: 4 samples instead of 2 gave noise 1.55 % instead of 2.20 %
        # for +7–35 % CPU, noise² × CPU 0.79–0.83 against 1.19–1.57). Under a top as sharp as a
        # car paint's clear coat (α 0.005) more light samples weigh the light strategy up where
        # the coat mirrors the light, which only BSDF sampling finds well: the presets scene's
        # variance went 13.9 → 24.2, the car paint's share 26 → 41 % (benchmarks/peers/diagnose).
        # The shadow-ray buffers are sized for it (integrator.py).
        more = kind == km.TABULATED and km.tabulated.more_light_samples(MT.tables, int(prm[0]))
        reps = S.glossy_light_samples if (kind == km.CONDUCTOR or kind == km.TABULATED) else 1
        if more:
            reps *= TABLE_NEE
        if all_lights and not delta_only:
            for k in range(S.nee_all * reps):
                lk = LT.sel_active[k % S.nee_all]
                # Every light its own stratified 2-D sample: the light slot under the sampler's
                # scramble of dimension dim + k·DIM_NEXT_LIGHT (beyond every bounce's slots).
                # Hashed numbers for the lights after the first had 3.3× the variance of their
                # light alone (tests/test_nee_all_lights.py); the IES room's sphere 2×.
                ul0, ul1 = get2(smode, ps, key[i], smp, bounce_dim(segment, SLOT_LIGHT) + k * DIM_NEXT_LIGHT)
                wk, dk, vk, pk, dlk, wok, live_k, etri = _light_sample(S, LT, TX, lk, p, ul0, ul1,
                                                                       fs, ft, ns, ng)
                if live_k and S.gated:
                    live_k = _allowed(S, lk, etri, rs, _lobe_class(S, kind, m, wi_l[2] * wok[2] > 0.0))
                if live_k and in_chain and S.caustic_light[lk]:
                    live_k = False
                if live_k:
                    f, bpdf = km.eval_pdf(MT.tables, kind, dist_code, mask_code, prm, 0, wi_l, wok)
                    _nee(S, segment, sl, bt, p, ng, LightSample(wk, dk, vk, pk, dlk), float(reps), f, bpdf,
                         S.light_shadow[lk], shadows, counts)
        elif can_nee and not delta_only:
            for r in range(reps):
                if r > 0:
                    # one more (pick, sample) pair from the next light slots
                    u_r, _ = get2(smode, ps, key[i], smp, bounce_dim(segment, SLOT_LIGHT_PICK) + r * DIM_NEXT_LIGHT)
                    li, sel_p = ld.select(LT, p, u_r)
                    live = False
                    if li >= 0 and sel_p > 0.0:
                        ul0, ul1 = get2(smode, ps, key[i], smp, bounce_dim(segment, SLOT_LIGHT) + r * DIM_NEXT_LIGHT)
                        wi_w, dist, value, lpdf, is_delta, wo_n, live, etri = _light_sample(
                            S, LT, TX, li, p, ul0, ul1, fs, ft, ns, ng)
                        if live and S.gated:
                            live = _allowed(S, li, etri, rs, _lobe_class(S, kind, m, wi_l[2] * wo_n[2] > 0.0))
                if live and in_chain and S.caustic_light[li]:
                    live = False
                if live:
                    f, bpdf = km.eval_pdf(MT.tables, kind, dist_code, mask_code, prm, 0, wi_l, wo_n)
                    _nee(S, segment, sl, bt, p, ng, LightSample(wi_w, dist, value, lpdf, is_delta), sel_p * reps,
                         f, bpdf, S.light_shadow[li], shadows, counts)
        # how light sampling competed here: the MIS weight of a light a ray from here hits
        # counts the light samples taken here
        via_nee = ((VIA_ALL_LIGHTS if all_lights else VIA_SAMPLED) + (VIA_SPLIT if reps > 1 or kind == km.TABULATED else 0)
                   + (VIA_TABLE if more else 0))
        # 4c. smooth glass, a coated kind's smooth top: the lights its mirror shows, every sample;
        # a coated kind's sharp top seen by the camera: the lights a direction from its lobe
        # meets, every sample
        probed = False
        top_share = 0.0
        # (not at a caster vertex of a caustic path the photons take: they count its mirror too)
        if S.probed.shape[0] > 0 and not last and not in_chain:
            refl = km.chosen_reflectance(MT.tables, kind, prm, wi_l)
            if refl > 0.0:
                probed = True
                r = _world(fs, ft, ns, (-wi_l[0], -wi_l[1], wi_l[2]))
                if _dot(r, ng) > 0.0:          # else _continue drops the mirror ray too
                    _probe_reflection(S, LT, segment, sl, bt, p, ng, r, refl, shadows, counts)
            elif can_nee and camera:
                uq0, uq1 = get2(smode, ps, key[i], smp, bounce_dim(segment, SLOT_BSDF) + DIM_NEXT_LIGHT)
                top_share, wq = km.sharp_top(MT.tables, kind, dist_code, prm, wi_l, uq0, uq1)
                if top_share > 0.0:
                    fq, pq = km.eval_pdf(MT.tables, kind, dist_code, mask_code, prm, 0, wi_l, wq)
                    r = _world(fs, ft, ns, wq)
                    if pq > 0.0 and _dot(r, ng) > 0.0:
                        s_q = top_share / pq
                        _probe_lobe(S, LT, segment, sl, bt, p, ng, r, (fq[0] * s_q, fq[1] * s_q, fq[2] * s_q),
                                    pq, via_nee, shadows, counts)
        # 5. continuation
        if not last:
            ub0, ub1 = get2(smode, ps, key[i], smp, bounce_dim(segment, SLOT_BSDF))
            wo, weight, spdf, sdelta = km.sample(MT.tables, kind, dist_code, mask_code, prm, 0, wi_l,
                                                 ub0, ub1, u_lobe)
            if weight[0] > 0.0 or weight[1] > 0.0 or weight[2] > 0.0:
                via = VIA_DELTA if sdelta else via_nee
                if probed and sdelta and wo[2] > 0.0:      # the mirror, not a refraction or the body
                    via = VIA_PROBED
                if top_share > 0.0 and u_lobe < top_share:  # the sampler took the top's lobe
                    via |= VIA_TOP_PROBED
                nrt = _lobe_class(S, kind, m, wi_l[2] * wo[2] > 0.0) if S.track else 0
                if features and delta_only and sdelta:
                    nrt |= FEATURES_PENDING
                if caustics and S.caustic_plain[m_surface]:
                    if camera:
                        if not S.caustic_caster[m_surface] and not sdelta:
                            nrt |= CAUSTIC_FROM
                    elif in_chain:
                        nrt |= CAUSTIC_CHAIN
                cont = Continuation(_world(fs, ft, ns, wo), wo[2], weight, spdf, via)
                _continue(S, segment, sl, key[i], bt, p, ng, cont, nrt, rs, nxt, counts)
    # Emission queued behind a deferred layered pdf (``_light_hit``): each lane's pdf estimated
    # once, its rows weighed. After the lane loop, so that compiling this kernel reaches the
    # layered lane (compiled by another process, kernels/cache.py) after everything else.
    queued = counts[4]
    lane = -1
    pdf = 0.0
    estimates = 0
    for k in range(queued):
        i = PD[k, 0]
        if i != lane:
            lane = i
            pdf = _deferred_pdf(ST, TX, dfr, i, key[i], segment - 1, walk)
            estimates += 1
        _weighted_to((PC[k, 0], PC[k, 1], PC[k, 2]), power_heuristic(pdf, PC[k, 3]), S, found, slot[i],
                     PD[k, 1], L, sh_c)
    counts[4] = estimates


@kernel(nogil=True)
def add_unoccluded(sh_slot, sh_c, blocked, L):
    """Shadow-ray contributions of the unblocked rays (embree's OCCLUDED answer: −1 = free)."""
    for k in range(sh_slot.shape[0]):
        if blocked[k] == -1:
            _add(L, sh_slot[k], (sh_c[k, 0], sh_c[k, 1], sh_c[k, 2]))
