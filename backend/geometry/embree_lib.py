"""The embree library embreex loaded, called directly: geometry filled by NumPy, scenes committed
without the GIL, and the addresses of the ray queries for the compiled kernels (kernels/trace.py).

embreex's ``TriangleMesh`` copies every vertex coordinate with Python-level indexing: about 2.7 µs
a triangle, all of it holding the GIL (1 M triangles: 2.7 s of a 6.4 s render). Here the same four
embree calls (new geometry, new buffers, commit, attach) are made through ctypes on the embree
library that embreex loaded, and the buffers are filled by NumPy (1 M triangles: ~30 ms). A
geometry may have several time steps (one vertex buffer each: motion blur); rays carry a time.

embreex keeps its scene handle in a C field that Python cannot read. Its object layout (a Cython
class: scene handle, ``is_committed``, the device object) is checked against what Python can see
— the public ``is_committed`` written with a marker and read back at its offset, the device
object's address — before the handle is used. Any mismatch (another embreex build, a library that
cannot be found) makes :func:`triangle_scene` return None; the caller then uses ``TriangleMesh``
and embreex's own ray queries.
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


def _libraries():
    """Handles through which to reach the embree library embreex's own modules use. POSIX: the
    extension module itself (dlsym on its handle searches the libraries it links against, so the
    answer is its embree even when another one is loaded too — bpy bundles its own, and calling
    that one with embreex's scene deadlocks in its task scheduler). Windows, where a module does
    not re-export what it imports: the DLL that delvewheel put next to embreex."""
    from embreex import rtcore_scene
    if os.name != "nt":
        yield rtcore_scene.__file__
        return
    import embreex
    base = os.path.dirname(embreex.__file__)
    for folder in (base + ".libs", base):
        yield from sorted(glob.glob(os.path.join(folder, "embree4*.dll")))


@lru_cache(maxsize=1)
def _embree():
    """The embree library's functions, or None."""
    import embreex.rtcore_scene  # noqa: F401  (loads the library first, with its dependencies)
    for path in _libraries():
        try:
            lib = ctypes.CDLL(path)
            fns = (lib.rtcNewGeometry, lib.rtcSetNewGeometryBuffer, lib.rtcCommitGeometry,
                   lib.rtcAttachGeometry, lib.rtcReleaseGeometry, lib.rtcGetDeviceError,
                   lib.rtcSetGeometryTimeStepCount, lib.rtcCommitScene, lib.rtcIntersect1,
                   lib.rtcOccluded1)
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
        lib.rtcSetGeometryTimeStepCount.argtypes = [vp, ctypes.c_uint]
        lib.rtcSetGeometryTimeStepCount.restype = None
        lib.rtcCommitScene.argtypes, lib.rtcCommitScene.restype = [vp], None
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


class EmbreeScene:
    """An embreex scene (kept alive: it owns the embree scene) with its C handle."""

    def __init__(self, scene, handle: int, device: int):
        self.scene = scene
        self.handle = handle
        self.device = device
        self.committed = False

    def commit(self) -> None:
        """Build the BVH (embree's own threads; ctypes releases the GIL meanwhile)."""
        if not self.committed:
            _embree().rtcCommitScene(self.handle)
            self.scene.is_committed = 1
            self.committed = True


def query_addresses() -> tuple[int, int]:
    """(rtcIntersect1, rtcOccluded1) as integers for kernels/trace.py."""
    lib = _embree()
    return (ctypes.cast(lib.rtcIntersect1, ctypes.c_void_p).value,
            ctypes.cast(lib.rtcOccluded1, ctypes.c_void_p).value)


def _attach(lib, handles, steps: list[np.ndarray]) -> bool:
    """One triangle geometry over a soup given at one or more time steps (each (T, 3, 3) float32;
    primitive i = triangle i); False if embree refused it."""
    scene_handle, device_handle = handles
    t = steps[0].shape[0]
    if t == 0:
        return True                          # nothing to attach (embree refuses empty buffers)
    geom = lib.rtcNewGeometry(device_handle, _GEOMETRY_TYPE_TRIANGLE)
    if not geom:
        return False
    if len(steps) > 1:
        lib.rtcSetGeometryTimeStepCount(geom, len(steps))
    # The buffers embreex makes: float3 vertices with a 16-byte stride (one buffer per time step),
    # one index triple per triangle over its own three vertices.
    for slot, vertices in enumerate(steps):
        vbuf = lib.rtcSetNewGeometryBuffer(geom, _BUFFER_TYPE_VERTEX, slot, _FORMAT_FLOAT3, 16, 3 * t)
        if not vbuf:
            lib.rtcReleaseGeometry(geom)
            return False
        v = np.ctypeslib.as_array(ctypes.cast(vbuf, ctypes.POINTER(ctypes.c_float)), shape=(3 * t, 4))
        v[:, :3] = vertices.reshape(3 * t, 3)
        v[:, 3] = 0.0
    ibuf = lib.rtcSetNewGeometryBuffer(geom, _BUFFER_TYPE_INDEX, 0, _FORMAT_UINT3, 12, t)
    if not ibuf:
        lib.rtcReleaseGeometry(geom)
        return False
    i = np.ctypeslib.as_array(ctypes.cast(ibuf, ctypes.POINTER(ctypes.c_uint32)), shape=(3 * t,))
    i[:] = np.arange(3 * t, dtype=np.uint32)
    lib.rtcCommitGeometry(geom)
    lib.rtcAttachGeometry(scene_handle, geom)
    lib.rtcReleaseGeometry(geom)
    return lib.rtcGetDeviceError(device_handle) == 0


def triangle_scene(vertices: np.ndarray, moving: list[np.ndarray] | None = None) -> EmbreeScene | None:
    """An uncommitted scene over a (T, 3, 3) float32 soup: geometry 0 holds triangles 0 … T − 1
    of ``vertices`` (primID = triangle index); with ``moving`` (the positions of the last M of
    them at K ≥ 2 equally spaced times over the shutter, each (M, 3, 3)), those M triangles are
    geometry 1 instead, traced at the ray's time (primID = triangle index − (T − M)). None where
    this route is not available."""
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
    m = moving[0].shape[0] if moving else 0
    fixed = vertices[:vertices.shape[0] - m]
    # Geometry 0: the fixed triangles; 1: the moving ones (0 when there are no fixed ones, whose
    # offset T − M is then 0 too: kernels/trace.py adds it to primID for geometry 1 only).
    if not _attach(lib, handles, [fixed]):
        return None
    if m and not _attach(lib, handles, [np.ascontiguousarray(s, np.float32) for s in moving]):
        return None
    return EmbreeScene(scene, *handles)
