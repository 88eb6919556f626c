"""Evaluated Blender meshes → the ``.npz`` mesh arrays of docs/scene-format.md, with foreach_get.

Every array is read in bulk (no Python loop per vertex or triangle): triangle corners from
``loop_triangles``, vertex indices through the corner→vertex map, materials through the
triangle→polygon map. Normals follow the mesh's normal domain: flat meshes store none (the
renderer uses the geometric normal), smooth meshes per-vertex normals, meshes with sharp edges or
custom normals per-corner normals. UVs are per corner (the render-active UV map).
"""
from __future__ import annotations

import numpy as np


def _attribute(me, name: str, domain: str, data_type: str):
    attr = me.attributes.get(name)
    if attr is not None and attr.domain == domain and attr.data_type == data_type:
        return attr
    return None


def mesh_arrays(me) -> dict | None:
    """Arrays of one evaluated mesh, or None if it has no triangles."""
    me.calc_loop_triangles()
    nt = len(me.loop_triangles)
    if nt == 0:
        return None
    nv = len(me.vertices)
    nl = len(me.loops)

    positions = np.empty(nv * 3, np.float32)
    me.attributes["position"].data.foreach_get("vector", positions)

    tri_loops = np.empty(nt * 3, np.int32)
    me.loop_triangles.foreach_get("loops", tri_loops)

    corner_vert = _attribute(me, ".corner_vert", "CORNER", "INT")
    corner_to_vertex = np.empty(nl, np.int32)
    if corner_vert is not None:
        corner_vert.data.foreach_get("value", corner_to_vertex)
    else:                                    # older Blender: the same map through MeshLoop
        me.loops.foreach_get("vertex_index", corner_to_vertex)
    indices = corner_to_vertex[tri_loops]

    out = {"positions": positions.reshape(nv, 3), "indices": indices.reshape(nt, 3)}

    material_index = _attribute(me, "material_index", "FACE", "INT")
    if material_index is not None and len(me.materials) > 1:
        per_face = np.empty(len(me.polygons), np.int32)
        material_index.data.foreach_get("value", per_face)
        tri_face = np.empty(nt, np.int32)
        me.loop_triangle_polygons.foreach_get("value", tri_face)
        out["material_indices"] = np.maximum(per_face[tri_face], 0)

    domain = getattr(me, "normals_domain", "CORNER")
    if domain == "POINT":
        normals = np.empty(nv * 3, np.float32)
        me.vertex_normals.foreach_get("vector", normals)
        out["normals"] = normals.reshape(nv, 3)
    elif domain == "CORNER":
        normals = np.empty(nl * 3, np.float32)
        me.corner_normals.foreach_get("vector", normals)
        out["normals"] = normals.reshape(nl, 3)[tri_loops].reshape(nt, 3, 3)

    uv_layer = next((layer for layer in me.uv_layers if layer.active_render), me.uv_layers.active)
    if uv_layer is not None:
        uv = np.empty(nl * 2, np.float32)
        uv_layer.uv.foreach_get("vector", uv)
        out["uvs"] = uv.reshape(nl, 2)[tri_loops].reshape(nt, 3, 2)
    return out


def sanitise(arrays: dict, name: str, notes: list[str]) -> dict:
    """Replace non-finite values the loader would refuse (rare: broken custom normals/UVs)."""
    for key in ("positions", "normals", "uvs"):
        a = arrays.get(key)
        if a is not None and not np.isfinite(a).all():
            bad = int((~np.isfinite(a)).sum())
            if key == "positions":
                notes.append(f"mesh '{name}': {bad} non-finite vertex coordinate(s) set to 0")
                arrays[key] = np.nan_to_num(a, nan=0.0, posinf=0.0, neginf=0.0)
            else:
                notes.append(f"mesh '{name}': {bad} non-finite {key} value(s) (the {key} are dropped)")
                del arrays[key]
    return arrays


def write_npz(path, arrays: dict) -> None:
    # Uncompressed: writing is ~10× faster than deflate and the files are temporary or local.
    with open(path, "wb") as f:
        np.savez(f, **arrays)
