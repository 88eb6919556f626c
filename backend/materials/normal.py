"""Shading normals of a material: a normal given in the material's local frame — on a whole material (scene-file
``"normal"`` on any material, loader.parse_material) or on one interface of a layered stack.

Local frame: x = the UV tangent dP/du, y = n × x, z = the surface's (interpolated) normal; so a
tangent-space normal map is Blender's Normal Map node in Tangent Space for UVs that are not
mirrored. The value is a constant vector (z > 0), or an image texture whose RGB encodes
(x, y, z) = RGB · 2 − 1 (OpenGL convention: green = +y; a "Non-Color" image).

A bump map (scene-file ``"bump"`` on any material; Blender's Bump node): a height field h(u, v)
tilts the normal against its surface gradient, n' = normalize(n − d·∇h), d the distance; the
gradient follows the mesh's UV map, so the same texture on a larger object tilts less.
"""
from __future__ import annotations

import numpy as np

from ..scene.reader import Node


class NormalParam:
    """A shading normal in the local frame (x = UV tangent, z = the
    surface normal): a constant vector, or a normal-map texture (RGB · 2 − 1, tangent space).
    ``bind`` gives unit normals as (3, 1) or (3, n); normals are kept above the surface."""

    def __init__(self, param, texture: bool):
        self.param = param
        self.texture = texture
        self.is_constant = param.is_constant

    def bind(self, uv):
        v = np.asarray(self.param.bind(uv), dtype=np.float64).reshape(-1, 3)
        if self.texture:
            v = 2.0 * v - 1.0
        v = v.copy()
        v[:, 2] = np.maximum(v[:, 2], 1e-3)
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        if v.shape[0] == 1 and np.allclose(v[0], [0.0, 0.0, 1.0], atol=1e-12):
            return None
        return np.ascontiguousarray(v.T)


def parse_normal(inode: Node) -> NormalParam | None:
    if not inode.has("normal"):
        return None
    raw = inode.value["normal"]
    texture = isinstance(raw, dict)
    p = inode.param("normal", channels=3, lo=None, color=False)
    if not texture:
        v = np.asarray(p.bind(None)).reshape(3)
        if v[2] <= 0 or not np.any(v):
            raise inode.fail("expected a normal [x, y, z] pointing out of the surface (z > 0)", "normal")
    return NormalParam(p, texture)


class Bump:
    """A material's bump map: ``height`` (a Param: a texture, or a constant that tilts nothing)
    times ``distance`` [scene units per unit of the height value, negative when inverted], mixed
    with the unbumped normal by ``strength`` in [0, 1] (kernels/integrator.py ``_bumped_normal``)."""

    def __init__(self, height, distance: float, strength: float):
        self.height = height
        self.distance = distance
        self.strength = strength


def parse_bump(node: Node) -> Bump | None:
    """``"bump": {"height": number or texture, "distance": 1.0, "strength": 1.0, "invert": false}``;
    None when absent or when it cannot tilt the normal (constant height, zero distance or
    strength)."""
    if not node.has("bump"):
        return None
    b = node.child("bump")
    b.require_object()
    height = b.param("height", channels=1, lo=None, color=False)
    distance = b.number("distance", 1.0)
    strength = b.number("strength", 1.0, lo=0.0, hi=1.0)
    invert = b.boolean("invert", False)
    b.finish()
    if height.is_constant or distance == 0.0 or strength == 0.0:
        return None
    return Bump(height, -distance if invert else distance, strength)


class SurfaceDetail:
    """What tilts the shading normal of a material or of one interface of a layered stack: a
    normal map (``normal``, mixed with the surface normal by ``strength``, Blender's Normal Map
    Strength) and a bump map on top of it. A material's goes into its row of the material table
    (the integrator tilts the lane's normal); an interface's into the stack table
    (kernels/layered/table.py ``bind_iface`` tilts the interface in the lane's frame)."""

    def __init__(self, normal: NormalParam | None, strength: float, bump: Bump | None):
        self.normal = normal
        self.strength = strength
        self.bump = bump

    @property
    def is_constant(self) -> bool:
        return self.bump is None and (self.normal is None or self.normal.is_constant)


def parse_detail(node: Node) -> SurfaceDetail | None:
    """``"normal"``, ``"normal_strength"`` and ``"bump"`` of a material or an interface; None when
    nothing tilts the normal."""
    normal = parse_normal(node)
    strength = node.number("normal_strength", 1.0, lo=0.0)
    bump = parse_bump(node)
    if normal is not None and strength == 0.0:
        normal = None
    if normal is None and bump is None:
        return None
    return SurfaceDetail(normal, strength, bump)
