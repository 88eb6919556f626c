"""Camera rays per lane: pixel-filter importance sampling, the Blender camera model, thin lens.

Camera parameter vector ``cam`` (float64, see ``camera_vector``):
  [0] kind (0 perspective, 1 orthographic)   [1:13] to_world rows 0–2 (3 × 4, row-major)
  [13:25] frame corners tr, br, bl, tl (camera space)   [25] clip_start  [26] clip_end
  [27] focus distance  [28] aperture radius  [29] blades  [30] rotation [rad]  [31] ratio
Film position (s, t) ∈ [0, 1]² (s right, t down; pixel (0, 0) top-left) maps bilinearly onto the
frame corners (Blender's ``Camera.view_frame``, sensor fit and shift included); the camera looks
down its local −Z; clip distances are measured along the view axis.

Pixel filter (as Cycles): each sample's offset from the pixel centre is drawn from the filter's
separable 1-D profile by inverting its tabulated CDF, so every sample has weight 1.
"""
from __future__ import annotations

import math

from collections import namedtuple

import numpy as np

from .jit import kernel
from .rng import BOUNCE_BASE, DIM_FILTER, DIM_LENS, SLOT_TIME, path_key
from .sampler import get2, pixel_seed
from .warp import disk_concentric

#: A pixel filter as the camera kernel samples it (backend/film.py ``PixelFilter.tables``):
#: the inverted cumulative table, its grid and inverse, the kink flag and the support [pixels].
PixelFilterTable = namedtuple("PixelFilterTable", ["cdf", "grid", "inverse", "kinked", "support"])

CAMERA_SIZE = 32


def camera_vector(camera) -> np.ndarray:
    c = np.zeros(CAMERA_SIZE)
    c[0] = 1.0 if camera.kind == "orthographic" else 0.0
    c[1:13] = np.asarray(camera.to_world, np.float64)[:3, :4].ravel()
    c[13:25] = np.asarray(camera.frame, np.float64).ravel()
    c[25] = camera.clip_start
    c[26] = camera.clip_end if np.isfinite(camera.clip_end) else np.inf
    c[27] = camera.focus_distance
    c[28] = camera.aperture_radius
    c[29] = camera.blades
    c[30] = camera.rotation
    c[31] = camera.ratio
    return c


@kernel
def filter_offset(cdf, grid, inverse, kinked, width, u):
    """Offset from the pixel centre [pixels] for u in [0, 1): the inverse of the filter's CDF
    (piecewise linear between table nodes), centred and scaled to the filter's support. A lookup in
    the uniform-u table where its cell holds no CDF node (exact there), else a binary search."""
    m = kinked.shape[0]
    x = u * m
    i = min(int(x), m - 1)
    if not kinked[i]:
        lo_v = inverse[i]
        return (lo_v + (x - i) * (inverse[i + 1] - lo_v) - 0.5) * width
    lo = 0
    hi = cdf.shape[0] - 1
    while hi - lo > 1:            # largest lo with cdf[lo] <= u
        mid = (lo + hi) >> 1
        if cdf[mid] <= u:
            lo = mid
        else:
            hi = mid
    span = cdf[lo + 1] - cdf[lo]
    x = grid[lo] + ((u - cdf[lo]) / span * (grid[lo + 1] - grid[lo]) if span > 0.0 else 0.0)
    return (x - 0.5) * width


@kernel
def _aperture(cam, u0, u1):
    blades = int(cam[29])
    if blades < 3:
        x, y = disk_concentric(u0, u1)
    else:
        # Uniform point in a regular polygon with corners on the unit circle (as Cycles): pick
        # one of the equal triangles (centre, corner k, corner k+1), then a point in it.
        k = min(int(u0 * blades), blades - 1)
        a = math.sqrt(u0 * blades - k)
        step = 2.0 * math.pi / blades
        rot = cam[30]
        c0x, c0y = math.cos(k * step + rot), math.sin(k * step + rot)
        c1x, c1y = math.cos((k + 1) * step + rot), math.sin((k + 1) * step + rot)
        x = a * ((1.0 - u1) * c0x + u1 * c1x)
        y = a * ((1.0 - u1) * c0y + u1 * c1y)
    return x, y * cam[31]


@kernel
def generate(cam, s, t, lens, l0, l1):
    """World ray (o, d unit, tmin, tmax) through film position (s, t); ``lens`` enables the
    thin-lens sample (l0, l1)."""
    fx = cam[22] + s * (cam[13] - cam[22]) + t * (cam[19] - cam[22])
    fy = cam[23] + s * (cam[14] - cam[23]) + t * (cam[20] - cam[23])
    fz = cam[24] + s * (cam[15] - cam[24]) + t * (cam[21] - cam[24])
    if cam[0] == 0.0 and not (lens and cam[28] > 0.0 and cam[27] > 0.0):
        # Pinhole: normalise once, in world space. cos_axis = −fz/|f| and scale = |M f|/|f|, so
        # the clip distances scale by |M f|/(−fz); the film plane lies at z = −1 (fz < 0).
        wx = cam[1] * fx + cam[2] * fy + cam[3] * fz
        wy = cam[5] * fx + cam[6] * fy + cam[7] * fz
        wz = cam[9] * fx + cam[10] * fy + cam[11] * fz
        nw = math.sqrt(wx * wx + wy * wy + wz * wz)
        inv = 1.0 / nw
        along = nw / max(-fz, 1e-12 * nw)
        tmax = cam[26] * along if math.isfinite(cam[26]) else np.inf
        return (cam[4], cam[8], cam[12]), (wx * inv, wy * inv, wz * inv), cam[25] * along, tmax
    if cam[0] == 1.0:
        ox, oy, oz = fx, fy, 0.0
        dx, dy, dz = 0.0, 0.0, -1.0
    else:
        ox, oy, oz = 0.0, 0.0, 0.0
        inv_n = 1.0 / math.sqrt(fx * fx + fy * fy + fz * fz)
        dx, dy, dz = fx * inv_n, fy * inv_n, fz * inv_n
    cos_axis = max(-dz, 1e-12)
    if lens and cam[28] > 0.0 and cam[27] > 0.0:
        f = cam[27] / cos_axis
        px, py, pz = ox + dx * f, oy + dy * f, oz + dz * f
        ax, ay = _aperture(cam, l0, l1)
        ox += ax * cam[28]
        oy += ay * cam[28]
        dx, dy, dz = px - ox, py - oy, pz - oz
        inv_n = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx * inv_n, dy * inv_n, dz * inv_n
        cos_axis = max(-dz, 1e-12)
    m = cam[1:13]
    o = (m[0] * ox + m[1] * oy + m[2] * oz + m[3],
         m[4] * ox + m[5] * oy + m[6] * oz + m[7],
         m[8] * ox + m[9] * oy + m[10] * oz + m[11])
    wx = m[0] * dx + m[1] * dy + m[2] * dz
    wy = m[4] * dx + m[5] * dy + m[6] * dz
    wz = m[8] * dx + m[9] * dy + m[10] * dz
    # The matrix may scale: clip distances scale with the length of the transformed direction.
    scale = math.sqrt(wx * wx + wy * wy + wz * wz)
    inv = 1.0 / scale if scale > 0.0 else 1.0
    d = (wx * inv, wy * inv, wz * inv)
    along = scale / cos_axis            # ray length per unit of view-axis depth
    tmin = cam[25] * along
    tmax = cam[26] * along if math.isfinite(cam[26]) else np.inf
    return o, d, tmin, tmax


@kernel
def generate_batch(cam, st, lens_u, use_lens, o, d, tmin, tmax):
    """Array form (tests): st (n, 2) film positions, lens_u (n, 2) or unused."""
    for i in range(st.shape[0]):
        l0 = lens_u[i, 0] if use_lens else 0.5
        l1 = lens_u[i, 1] if use_lens else 0.5
        oo, dd, a, b = generate(cam, st[i, 0], st[i, 1], use_lens, l0, l1)
        o[i, 0], o[i, 1], o[i, 2] = oo
        d[i, 0], d[i, 1], d[i, 2] = dd
        tmin[i] = a
        tmax[i] = b


@kernel
def filter_batch(cdf, grid, inverse, kinked, width, u, out):
    for i in range(u.shape[0]):
        out[i, 0] = filter_offset(cdf, grid, inverse, kinked, width, u[i, 0])
        out[i, 1] = filter_offset(cdf, grid, inverse, kinked, width, u[i, 1])


@kernel
def _moved(cm, tt, ro, rd):
    """A camera ray moved with the camera to shutter time tt: the change from the camera's
    transform interpolated between the two motion steps around tt, applied to the ray."""
    K = cm.shape[0]
    x = tt * (K - 1)
    k0 = min(int(x), K - 2)
    a = x - k0
    r0 = cm[k0]
    r1 = cm[k0 + 1]
    o = ((r0[0] + a * (r1[0] - r0[0])) * ro[0] + (r0[1] + a * (r1[1] - r0[1])) * ro[1]
         + (r0[2] + a * (r1[2] - r0[2])) * ro[2] + (r0[3] + a * (r1[3] - r0[3])),
         (r0[4] + a * (r1[4] - r0[4])) * ro[0] + (r0[5] + a * (r1[5] - r0[5])) * ro[1]
         + (r0[6] + a * (r1[6] - r0[6])) * ro[2] + (r0[7] + a * (r1[7] - r0[7])),
         (r0[8] + a * (r1[8] - r0[8])) * ro[0] + (r0[9] + a * (r1[9] - r0[9])) * ro[1]
         + (r0[10] + a * (r1[10] - r0[10])) * ro[2] + (r0[11] + a * (r1[11] - r0[11])))
    dx = (r0[0] + a * (r1[0] - r0[0])) * rd[0] + (r0[1] + a * (r1[1] - r0[1])) * rd[1] + (r0[2] + a * (r1[2] - r0[2])) * rd[2]
    dy = (r0[4] + a * (r1[4] - r0[4])) * rd[0] + (r0[5] + a * (r1[5] - r0[5])) * rd[1] + (r0[6] + a * (r1[6] - r0[6])) * rd[2]
    dz = (r0[8] + a * (r1[8] - r0[8])) * rd[0] + (r0[9] + a * (r1[9] - r0[9])) * rd[1] + (r0[10] + a * (r1[10] - r0[10])) * rd[2]
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    return o, (dx / n, dy / n, dz / n)


@kernel(nogil=True)
def camera_rays(cam, cam_motion, pixel_filter, width, height, seed, sampler, lanes, q, tmax32):
    """The primary rays of a work item (``lanes``, kernels/workitems.py Lanes): lane i is sample
    ``sample0 + i % spp`` of pixel ``pixels[i // spp]`` (flat index, row 0 = top). Writes into the
    RayQueue ``q`` (its first lanes) each lane's random-number key and the ray in float64
    (shading) and float32 (embree), and its clipped length into ``tmax32``. ``pixel_filter``: a
    PixelFilterTable. Motion blur (``lanes.time`` not empty): each lane's shutter time in [0, 1),
    stratified per pixel; the ray moves with the camera by ``cam_motion`` (K rows of a 3 × 4 change
    from the camera's transform, at K equally spaced times, interpolated linearly; empty: the
    camera does not move)."""
    cdf, grid, inverse, kinked, fwidth = pixel_filter
    pixels, spp, sample0, lane_time = lanes
    key, o, d, o32, d32 = q.key, q.o, q.d, q.o32, q.d32
    lens = cam[28] > 0.0 and cam[27] > 0.0
    inv_w = 1.0 / width
    inv_h = 1.0 / height
    # Nested over pixels and samples (no 64-bit integer division per lane: ~25 ns of ~60).
    for q_ in range(key.shape[0] // spp):
        pix = pixels[q_]
        ps = pixel_seed(seed, pix)
        px = pix % width
        py = pix // width
        for j in range(spp):
            i = q_ * spp + j
            smp = sample0 + j
            k = path_key(seed, pix, smp)
            key[i] = k
            f0, f1 = get2(sampler, ps, k, smp, DIM_FILTER)
            ox_ = filter_offset(cdf, grid, inverse, kinked, fwidth, f0)
            oy_ = filter_offset(cdf, grid, inverse, kinked, fwidth, f1)
            s = (px + 0.5 + ox_) * inv_w
            t = (py + 0.5 + oy_) * inv_h
            l0, l1 = get2(sampler, ps, k, smp, DIM_LENS) if lens else (0.5, 0.5)
            ro, rd, tmin, tm = generate(cam, s, t, lens, l0, l1)
            if lane_time.shape[0] > 0:
                tt = get2(sampler, ps, k, smp, BOUNCE_BASE + SLOT_TIME)[0]
                lane_time[i] = min(np.float32(tt), np.float32(0.99999994))
                if cam_motion.shape[0] > 0:
                    ro, rd = _moved(cam_motion, tt, ro, rd)
            # Start at the near clip plane.
            for c in range(3):
                o[i, c] = ro[c] + rd[c] * tmin
                d[i, c] = rd[c]
                o32[i, c] = o[i, c]
                d32[i, c] = rd[c]
            tmax32[i] = min(tm - tmin, 3e38)
