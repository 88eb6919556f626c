"""Triangle meshes: loading (.npz, inline JSON, built-in shapes), validation, clean-up.

A :class:`Mesh` is stored per corner for the attributes that can be discontinuous (normals, UVs),
because that is how Blender exports them (``corner_normals`` per loop triangle) and it makes
shading a pure gather: ``normals[tri, corner]``.

Precision: positions stay float32 (that is what embree traces and what Blender stores); the
renderer recomputes hit points in float64 from the vertices.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import LaminaError, SceneError
from ..scene.reader import Node


@dataclass
class Mesh:
    positions: np.ndarray                 # (V, 3) float32, object space
    indices: np.ndarray                   # (T, 3) int32
    normals: np.ndarray | None = None     # (T, 3, 3) float32 per-corner shading normals
    uvs: np.ndarray | None = None         # (T, 3, 2) float32 per-corner UVs
    material_indices: np.ndarray | None = None  # (T,) int32 slot per triangle

    @property
    def triangle_count(self) -> int:
        return int(self.indices.shape[0])


# --------------------------------------------------------------------------- loading

_ARRAYS = ("positions", "indices", "normals", "uvs", "material_indices")


def parse_mesh(node: Node) -> Mesh:
    """A mesh entry of the scene file (see docs/scene-format.md, ``meshes``)."""
    node.require_object()
    if node.has("shape"):
        mesh = _parse_shape(node)
    elif node.has("file"):
        mesh = _load_npz(node)
    else:
        arrays = {}
        for key in _ARRAYS:
            value = node.child(key, None).value
            if value is not None:
                arrays[key] = _inline_array(node, key, value)
        if "positions" not in arrays or "indices" not in arrays:
            raise node.fail("a mesh needs `file`, `shape`, or inline `positions` and `indices`")
        mesh = _build(node, arrays)
    node.finish()
    return mesh


def _inline_array(node: Node, key: str, value) -> np.ndarray:
    """A JSON list of lists of numbers as an array: integers for ``indices`` and
    ``material_indices``, finite numbers otherwise. Strings, booleans, nulls and ragged lists are
    errors naming the first offending element (NumPy would turn "1" into 1 or True into 1)."""
    integer = key in ("indices", "material_indices")
    stack = [(value, key)]
    while stack:
        v, where = stack.pop()
        if isinstance(v, list):
            stack.extend((c, f"{where}[{i}]") for i, c in reversed(list(enumerate(v))))
            continue
        bad = (isinstance(v, bool) or not isinstance(v, (int, float)) or
               (integer and not isinstance(v, int)) or
               (isinstance(v, float) and not math.isfinite(v)))
        if bad:
            from ..scene.reader import _describe
            kind = "an integer" if integer else "a finite number"
            raise node.fail(f"{where}: expected {kind}, got {_describe(v)}", key)
    try:
        a = np.array(value, dtype=np.int64 if integer else np.float64)
    except OverflowError:
        raise node.fail(f"{key}: an integer is out of range (at most {2 ** 63 - 1})", key) from None
    except (TypeError, ValueError):
        raise node.fail("expected a rectangular list of numbers", key) from None
    return a


def _load_npz(node: Node) -> Mesh:
    from ..limits import short
    file = node.string("file")
    path = node.ctx.existing_file(file, node.sub("file"), "mesh file")
    try:
        _check_npz_size(path)
        with np.load(path, allow_pickle=False) as data:
            unknown = [k for k in data.files if k not in _ARRAYS]
            if unknown:
                raise node.fail(f"unknown array {short(unknown[0])!r} in {short(file)} "
                                f"(allowed: {', '.join(_ARRAYS)})", "file")
            arrays = {k: data[k] for k in data.files}
    except SceneError:
        raise
    except LaminaError as exc:
        raise node.fail(f"cannot read mesh file {short(path, 200)}: {exc}", "file") from None
    except MemoryError:
        raise node.fail(f"cannot read mesh file {short(path, 200)}: not enough memory for its arrays",
                        "file") from None
    except Exception as exc:  # noqa: BLE001 - a damaged archive raises zipfile/zlib/OS/Value errors
        raise node.fail(f"cannot read mesh file {short(path, 200)} (a NumPy .npz archive): "
                        f"{type(exc).__name__}: {short(exc, 200)}", "file") from None
    return _build(node, arrays, prefix=f"{short(file)}: ")


def _check_npz_size(path) -> None:
    """Refuse an archive whose arrays would not fit in memory, from their headers, before any
    is read (a small compressed file can declare a huge array)."""
    import zipfile

    from ..limits import available_memory
    total = 0
    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            if not info.filename.endswith(".npy"):
                continue
            with zf.open(info) as f:
                version = np.lib.format.read_magic(f)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(f)
                else:
                    shape, _, dtype = np.lib.format.read_array_header_2_0(f)
            total += int(np.prod(shape, dtype=object)) * dtype.itemsize
    have = available_memory()
    if have is not None and total > have // 2:
        raise LaminaError(f"its arrays need {total / 2 ** 30:.1f} GiB, "
                          f"{have / 2 ** 30:.1f} GiB of memory available")


def _real(a: np.ndarray) -> bool:
    """Integer or floating point, not complex, bool or object."""
    return a.dtype.kind in "iuf"


def _build(node: Node, arrays: dict, prefix: str = "") -> Mesh:
    from ..limits import MAX_COORDINATE

    def fail(name, message):
        return node.fail(prefix + message, name if not prefix else "file")

    pos = np.asarray(arrays.get("positions"))
    idx = np.asarray(arrays.get("indices"))
    if pos.ndim != 2 or pos.shape[1] != 3 or not _real(pos):
        raise fail("positions", f"positions: expected real numbers of shape (V, 3), got {pos.shape} {pos.dtype}")
    if idx.ndim != 2 or idx.shape[1] != 3 or idx.dtype.kind not in "iu":
        raise fail("indices", f"indices: expected integer shape (T, 3), got {idx.shape} {idx.dtype}")
    if pos.shape[0] == 0 or idx.shape[0] == 0:
        raise fail("indices", "empty mesh (no vertices or no triangles)")
    if not np.all(np.isfinite(pos)):
        bad = int(np.argwhere(~np.isfinite(pos))[0, 0])
        raise fail("positions", f"positions[{bad}] is not finite (NaN or Inf)")
    big = np.abs(pos) > MAX_COORDINATE
    if big.any():
        bad = int(np.argwhere(big)[0, 0])
        raise fail("positions", f"positions[{bad}] = {pos[bad].tolist()}: coordinates must lie within "
                                f"±{MAX_COORDINATE:g}")
    if idx.min() < 0 or idx.max() >= pos.shape[0]:
        t = int(np.argwhere((idx < 0) | (idx >= pos.shape[0]))[0, 0])
        raise fail("indices", f"indices[{t}] = {idx[t].tolist()} out of bounds for {pos.shape[0]} vertices")
    t_count = idx.shape[0]
    idx = idx.astype(np.int32)
    normals = _corner_attribute(arrays.get("normals"), "normals", 3, idx, pos.shape[0], fail)
    uvs = _corner_attribute(arrays.get("uvs"), "uvs", 2, idx, pos.shape[0], fail)
    mat = arrays.get("material_indices")
    if mat is not None:
        mat = np.asarray(mat)
        if mat.shape != (t_count,) or mat.dtype.kind not in "iu":
            raise fail("material_indices", f"material_indices: expected integer shape ({t_count},), got {mat.shape} {mat.dtype}")
        if mat.size and mat.min() < 0:
            raise fail("material_indices", "material_indices: negative slot index")
        mat = np.minimum(mat, np.iinfo(np.int32).max).astype(np.int32)
    mesh = Mesh(pos.astype(np.float32), idx, normals, uvs, mat)
    return drop_degenerate(mesh, node)


def _corner_attribute(value, name, width, idx, vcount, fail):
    if value is None:
        return None
    from ..limits import MAX_COORDINATE
    a = np.asarray(value)
    if not _real(a):
        raise fail(name, f"{name}: expected real numbers, got {a.dtype}")
    per_vertex = a.shape == (vcount, width)
    if not per_vertex and a.shape != (idx.shape[0], 3, width):
        raise fail(name, f"{name}: expected shape ({vcount}, {width}) per vertex or "
                         f"({idx.shape[0]}, 3, {width}) per corner, got {a.shape}")
    # Checked before a per-vertex array is spread to the corners (a third of the work); the
    # message names a triangle that uses the bad value.
    flat = a.reshape(a.shape[0], -1)
    for bad_rows, what in ((~np.isfinite(flat), "is not finite (NaN or Inf)"),
                           (np.abs(flat) > MAX_COORDINATE, f"lie outside ±{MAX_COORDINATE:g}")):
        if bad_rows.any():
            bad = int(np.argwhere(bad_rows)[0, 0])
            if per_vertex:
                used = np.argwhere((idx == bad).any(axis=1))
                if used.size == 0:
                    continue                      # a vertex no triangle uses
                bad = int(used[0, 0])
            raise fail(name, f"{name} of triangle {bad} {what}")
    a = a.astype(np.float32, copy=False)
    return a[idx] if per_vertex else a


def drop_degenerate(mesh: Mesh, node: Node | None = None) -> Mesh:
    """Remove zero-area triangles (they have no normal); warn with their count."""
    from ..kernels.soup import nondegenerate
    keep = nondegenerate(mesh.positions, mesh.indices)
    if keep.all():
        return mesh
    dropped = int((~keep).sum())
    if node is not None:
        node.ctx.warn(node.path, f"{dropped} degenerate (zero-area) triangle(s) dropped")
    if not keep.any():
        if node is not None:
            raise node.fail("every triangle is degenerate (zero area): empty mesh")
    return Mesh(mesh.positions, mesh.indices[keep],
                None if mesh.normals is None else mesh.normals[keep],
                None if mesh.uvs is None else mesh.uvs[keep],
                None if mesh.material_indices is None else mesh.material_indices[keep])


# --------------------------------------------------------------------------- built-in shapes

def _parse_shape(node: Node) -> Mesh:
    # A size so small that float32 positions collapse gives zero-area triangles: an error (the
    # built-in shapes are otherwise never degenerate).
    return drop_degenerate(_shape(node), node)


def _shape(node: Node) -> Mesh:
    shape = node.string("shape", choices=("sphere", "rectangle", "cube", "disk"))
    if shape == "sphere":
        return uv_sphere(node.number("radius", 1.0, lo=0, lo_open=True),
                         node.integer("segments", 64, lo=3, hi=4096))
    if shape == "rectangle":
        size = node.vector("size", 2, [2.0, 2.0], lo=0)
        if np.any(size <= 0):
            raise node.fail("expected two positive numbers", "size")
        return rectangle(size[0], size[1])
    if shape == "disk":
        return disk(node.number("radius", 1.0, lo=0, lo_open=True), node.integer("segments", 64, lo=3, hi=4096))
    return cube(node.number("size", 2.0, lo=0, lo_open=True))


def uv_sphere(radius: float, segments: int) -> Mesh:
    """UV sphere centred at the origin with smooth normals and Blender-like UVs (u around Z)."""
    rings = max(2, segments // 2)
    theta = np.linspace(0.0, np.pi, rings + 1)             # from +Z down to -Z
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    n = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    uv = np.stack([p / (2 * np.pi), 1.0 - t / np.pi], axis=-1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a = (i * (segments + 1) + j).ravel()
    b = a + 1
    c = a + segments + 1
    d = c + 1
    tris = np.concatenate([np.stack([a, c, d], 1), np.stack([a, d, b], 1)])
    pos = n * radius
    mesh = Mesh(pos.astype(np.float32), tris.astype(np.int32),
                n[tris].astype(np.float32), uv[tris].astype(np.float32), None)
    return drop_degenerate(mesh)  # the pole fans contain zero-area triangles


def rectangle(size_x: float, size_y: float) -> Mesh:
    hx, hy = size_x / 2, size_y / 2
    pos = np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]], np.float32)
    tris = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    nrm = np.tile(np.array([0, 0, 1], np.float32), (2, 3, 1))
    return Mesh(pos, tris, nrm, uv[tris], None)


def disk(radius: float, segments: int) -> Mesh:
    ang = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], 1) * radius
    pos = np.concatenate([[[0, 0, 0]], ring]).astype(np.float32)
    k = np.arange(segments)
    tris = np.stack([np.zeros_like(k), 1 + k, 1 + (k + 1) % segments], 1).astype(np.int32)
    uv = (np.concatenate([[[0.0, 0.0]], ring[:, :2] / (2 * radius)]) + 0.5).astype(np.float32)
    nrm = np.tile(np.array([0, 0, 1], np.float32), (segments, 3, 1))
    return Mesh(pos, tris, nrm, uv[tris], None)


def cube(size: float) -> Mesh:
    h = size / 2
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1
            v = np.cross(n, u)
            c = n * h
            quad = [c - u * h - v * h, c + u * h - v * h, c + u * h + v * h, c - u * h + v * h]
            faces.append((quad, n))
    pos = np.array([p for quad, _ in faces for p in quad], np.float32)
    tris = []
    for f in range(6):
        o = 4 * f
        tris += [[o, o + 1, o + 2], [o, o + 2, o + 3]]
    tris = np.array(tris, np.int32)
    nrm = np.repeat(np.array([n for _, n in faces], np.float32), 2, axis=0)[:, None, :].repeat(3, 1)
    uv = np.tile(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32), (6, 1))
    return Mesh(pos, tris, nrm, uv[tris], None)
