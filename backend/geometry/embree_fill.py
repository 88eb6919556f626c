"""An embree triangle geometry filled by NumPy copies instead of embreex's element loop.

embreex's ``TriangleMesh`` copies every vertex coordinate with Python-level indexing: about 2.7 µs
a triangle, all of it holding the GIL (1 M triangles: 2.7 s of a 6.4 s render). Here the same four
embree calls (new geometry, new buffers, commit, attach) are made through ctypes on the embree
library that embreex loaded, and the buffers are filled by NumPy (1 M triangles: ~30 ms).

embreex keeps its scene handle in a C field that Python cannot read. Its object layout (a Cython
class: scene handle, ``is_committed``, the device object) is checked against what Python can see
— the public ``is_committed`` written with a marker and read back at its offset, the device
object's address — before the handle is used. Any mismatch (another embreex build, a library that
cannot be found) makes :func:`triangle_scene` return None; the caller then uses ``TriangleMesh``.
"""
from __future__ import annotations

import ctypes
import glob
import os
import sys
from functools import lru_cache

import numpy as np

# embree 4 enum values (include/embree4/rtcore_geometry.h, rtcore_buffer.h, rtcore_common.h).
_GEOMETRY_TYPE_TRIANGLE = 0
_BUFFER_TYPE_INDEX = 0
_BUFFER_TYPE_VERTEX = 1
_FORMAT_UINT3 = 0x5003
_FORMAT_FLOAT3 = 0x9003

_HEAD = 2 * ctypes.sizeof(ctypes.c_void_p)          # PyObject_HEAD: reference count, type
_SCENE_LAYOUT = (_HEAD, _HEAD + 8, _HEAD + 16)      # scene handle, is_committed (int), device object
_MARK = 0x5A17C0DE


def _library_paths() -> list[str]:
    """Where the embree library embreex loaded may be: the process's mapped files (Linux), then
    the folders wheels put bundled libraries in (auditwheel, delocate, delvewheel)."""
    paths = []
    try:
        with open("/proc/self/maps") as maps:
            paths += sorted({line.split()[-1] for line in maps if "libembree4" in line})
    except OSError:
        pass
    import embreex
    base = os.path.dirname(embreex.__file__)
    for folder in (base, os.path.join(base, ".dylibs"), base + ".libs"):
        for pattern in ("libembree4*.so*", "libembree4*.dylib", "embree4*.dll"):
            paths += sorted(glob.glob(os.path.join(folder, pattern)))
    return paths


@lru_cache(maxsize=1)
def _embree():
    """The embree library's functions, or None."""
    import embreex.rtcore_scene  # noqa: F401  (loads the library first, with its dependencies)
    for path in _library_paths():
        try:
            lib = ctypes.CDLL(path)
            fns = (lib.rtcNewGeometry, lib.rtcSetNewGeometryBuffer, lib.rtcCommitGeometry,
                   lib.rtcAttachGeometry, lib.rtcReleaseGeometry, lib.rtcGetDeviceError)
        except (OSError, AttributeError):
            continue
        vp = ctypes.c_void_p
        lib.rtcNewGeometry.argtypes, lib.rtcNewGeometry.restype = [vp, ctypes.c_int], vp
        lib.rtcSetNewGeometryBuffer.argtypes = [vp, ctypes.c_int, ctypes.c_uint, ctypes.c_int,
                                                ctypes.c_size_t, ctypes.c_size_t]
        lib.rtcSetNewGeometryBuffer.restype = vp
        lib.rtcCommitGeometry.argtypes, lib.rtcCommitGeometry.restype = [vp], None
        lib.rtcAttachGeometry.argtypes, lib.rtcAttachGeometry.restype = [vp, vp], ctypes.c_uint
        lib.rtcReleaseGeometry.argtypes, lib.rtcReleaseGeometry.restype = [vp], None
        lib.rtcGetDeviceError.argtypes, lib.rtcGetDeviceError.restype = [vp], ctypes.c_int
        del fns
        return lib
    return None


def _handles(scene, device):
    """(scene handle, device handle) read from embreex's objects, or None if their layout is not
    the one this module knows."""
    from embreex import rtcore as rtc
    from embreex import rtcore_scene as rtcs
    if (type(scene) is not rtcs.EmbreeScene or type(device) is not rtc.EmbreeDevice
            or rtcs.EmbreeScene.__basicsize__ != _HEAD + 24
            or rtc.EmbreeDevice.__basicsize__ != _HEAD + 8 or sys.maxsize < 2 ** 32):
        return None
    at_scene, at_committed, at_device = (id(scene) + k for k in _SCENE_LAYOUT)
    saved = scene.is_committed
    scene.is_committed = _MARK
    marked = ctypes.c_int.from_address(at_committed).value == _MARK
    scene.is_committed = saved
    if not marked or ctypes.c_void_p.from_address(at_device).value != id(device):
        return None
    scene_handle = ctypes.c_void_p.from_address(at_scene).value
    device_handle = ctypes.c_void_p.from_address(id(device) + _HEAD).value
    if not scene_handle or not device_handle:
        return None
    return scene_handle, device_handle


def triangle_scene(vertices: np.ndarray):
    """An uncommitted embreex scene holding one triangle geometry (id 0) over a (T, 3, 3) float32
    soup, primitive i = triangle i; None where this route is not available."""
    lib = _embree()
    if lib is None:
        return None
    from embreex import rtcore as rtc
    from embreex import rtcore_scene as rtcs
    device = rtc.EmbreeDevice()
    scene = rtcs.EmbreeScene(device)
    handles = _handles(scene, device)
    if handles is None:
        return None
    scene_handle, device_handle = handles
    t = vertices.shape[0]
    if t == 0:
        return scene                       # no geometry: every ray misses
    geom = lib.rtcNewGeometry(device_handle, _GEOMETRY_TYPE_TRIANGLE)
    if not geom:
        return None
    # The same buffers embreex makes: float3 vertices with a 16-byte stride, one index triple per
    # triangle over its own three vertices (primID = triangle index).
    vbuf = lib.rtcSetNewGeometryBuffer(geom, _BUFFER_TYPE_VERTEX, 0, _FORMAT_FLOAT3, 16, 3 * t)
    ibuf = lib.rtcSetNewGeometryBuffer(geom, _BUFFER_TYPE_INDEX, 0, _FORMAT_UINT3, 12, t)
    if not vbuf or not ibuf:
        lib.rtcReleaseGeometry(geom)
        return None
    v = np.ctypeslib.as_array(ctypes.cast(vbuf, ctypes.POINTER(ctypes.c_float)), shape=(3 * t, 4))
    v[:, :3] = vertices.reshape(3 * t, 3)
    v[:, 3] = 0.0
    i = np.ctypeslib.as_array(ctypes.cast(ibuf, ctypes.POINTER(ctypes.c_uint32)), shape=(3 * t,))
    i[:] = np.arange(3 * t, dtype=np.uint32)
    lib.rtcCommitGeometry(geom)
    geom_id = lib.rtcAttachGeometry(scene_handle, geom)
    lib.rtcReleaseGeometry(geom)
    if geom_id != 0 or lib.rtcGetDeviceError(device_handle) != 0:
        return None
    return scene
