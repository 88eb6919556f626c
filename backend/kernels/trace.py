"""Ray casting from compiled code: embree's ``rtcIntersect1`` / ``rtcOccluded1`` called per ray.

The functions' addresses come from the embree library embreex loaded (backend/geometry/embree_lib.py)
and are passed to the kernels as integers, called through ``_call_embree`` (an LLVM indirect
call): the kernels stay cacheable (no address is compiled in) and release the GIL. This is the
loop embreex's ``EmbreeScene.run`` runs, without its per-call result arrays, and with each ray's
``time`` set (motion blur: geometry with several time steps, geometry/accel.py).

The ray and hit travel in one 16-byte-aligned scratch block of ``RAYHIT_WORDS`` 32-bit words laid
out as embree 4's ``RTCRayHit`` (include/embree4/rtcore_ray.h): ray org xyz, tnear, dir xyz, time,
tfar, mask, id, flags (words 0-11); hit Ng xyz, u, v, primID, geomID, instID[1], instPrimID[1]
(words 12-20). ``rtcOccluded1`` reads the ray part only and sets tfar to −inf when blocked.
"""
from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from .jit import inlined, kernel

RAYHIT_WORDS = 32                  # 128 bytes: RTCRayHit (84 used) plus alignment slack
_INVALID = np.uint32(0xFFFFFFFF)


@intrinsic
def _call_embree(typingctx, fn, scene, ray):
    """fn(scene, ray, NULL) for integer addresses: rtcIntersect1 / rtcOccluded1 without
    arguments structure."""
    sig = types.void(types.intp, types.intp, types.intp)

    def codegen(context, builder, signature, args):
        ptr = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [ptr, ptr, ptr])
        target = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(target, [builder.inttoptr(args[1], ptr), builder.inttoptr(args[2], ptr),
                              ir.Constant(ptr, None)])
        return context.get_dummy_value()

    return sig, codegen


@kernel
def _aligned_block(scratch):
    """(float32 words, uint32 words, address) of a 16-byte-aligned RTCRayHit inside scratch."""
    addr = scratch.ctypes.data
    skip = ((16 - addr % 16) % 16) // 4
    f = scratch[skip:skip + 24]
    return f, f.view(np.uint32), addr + 4 * skip


@inlined
def _load_ray(f, w, o32, d32, tmax32, time32, i):
    """Ray i into the RTCRay words: origin, tnear 0, direction, time (0 without times), tfar,
    mask all ones, id and flags 0 (as embreex sets them)."""
    f[0], f[1], f[2], f[3] = o32[i, 0], o32[i, 1], o32[i, 2], np.float32(0.0)
    f[4], f[5], f[6] = d32[i, 0], d32[i, 1], d32[i, 2]
    f[7] = time32[i] if time32.shape[0] > 0 else np.float32(0.0)
    f[8] = tmax32[i]
    w[9], w[10], w[11] = _INVALID, np.uint32(0), np.uint32(0)


@kernel(nogil=True)
def intersect_rays(fn, scene, offset1, scratch, o32, d32, tmax32, time32, prim, b1, b2):
    """Closest hits: prim (int32 scene triangle index, −1 = miss), b1, b2 (float32), and each
    hit's distance written into tmax32 (as embreex does). Geometry 1's primitives are scene
    triangles offset1 … (the moving ones, geometry/embree_lib.py). ``time32`` empty: every ray
    at time 0."""
    f, w, addr = _aligned_block(scratch)
    for i in range(o32.shape[0]):
        _load_ray(f, w, o32, d32, tmax32, time32, i)
        w[17], w[18], w[19] = _INVALID, _INVALID, _INVALID
        _call_embree(fn, scene, addr)
        g = w[18]
        if g == _INVALID:
            prim[i] = -1
        elif g == 1:
            prim[i] = np.int32(w[17]) + offset1
        else:
            prim[i] = np.int32(w[17])
        tmax32[i] = f[8]
        b1[i] = f[15]
        b2[i] = f[16]


@kernel(nogil=True)
def occluded_rays(fn, scene, scratch, o32, d32, tmax32, time32, blocked):
    """blocked[i] = 0 (embree's geometry id answer of embreex) where something lies on the
    segment (0, tmax), −1 where it is free."""
    f, w, addr = _aligned_block(scratch)
    for i in range(o32.shape[0]):
        _load_ray(f, w, o32, d32, tmax32, time32, i)
        _call_embree(fn, scene, addr)
        blocked[i] = np.int32(0) if f[8] < 0.0 else np.int32(-1)


@inlined
def intersect_one(fn, scene, offset1, f, w, addr, o, d, tmax):
    """One ray (float64 tuples, time 0) through an RTCRayHit block from ``_aligned_block``:
    (scene triangle index or −1, hit distance, b1, b2). For code that follows one path at a time
    (kernels/caustics.py)."""
    f[0], f[1], f[2], f[3] = np.float32(o[0]), np.float32(o[1]), np.float32(o[2]), np.float32(0.0)
    f[4], f[5], f[6], f[7] = np.float32(d[0]), np.float32(d[1]), np.float32(d[2]), np.float32(0.0)
    f[8] = np.float32(min(tmax, 3e38))
    w[9], w[10], w[11] = _INVALID, np.uint32(0), np.uint32(0)
    w[17], w[18], w[19] = _INVALID, _INVALID, _INVALID
    _call_embree(fn, scene, addr)
    g = w[18]
    if g == _INVALID:
        return -1, np.inf, 0.0, 0.0
    pr = np.int64(w[17]) + (offset1 if g == 1 else 0)
    return pr, np.float64(f[8]), np.float64(f[15]), np.float64(f[16])


@inlined
def occluded_one(fn, scene, f, w, addr, o, d, tmax):
    """Whether something lies on the segment (0, tmax) of one ray (see ``intersect_one``)."""
    f[0], f[1], f[2], f[3] = np.float32(o[0]), np.float32(o[1]), np.float32(o[2]), np.float32(0.0)
    f[4], f[5], f[6], f[7] = np.float32(d[0]), np.float32(d[1]), np.float32(d[2]), np.float32(0.0)
    f[8] = np.float32(min(tmax, 3e38))
    w[9], w[10], w[11] = _INVALID, np.uint32(0), np.uint32(0)
    _call_embree(fn, scene, addr)
    return f[8] < 0.0
