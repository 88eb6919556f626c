"""World → ``world``: a constant colour or an equirectangular Environment Texture."""
from __future__ import annotations

import warnings

from ..util import matrix_rows, rgb
from .nodes import _follow, label


def _tree(world):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        use = getattr(world, "use_nodes", True)
    return world.node_tree if use and world.node_tree is not None else None


def world_json(world, images, notes: list[str]) -> dict:
    if world is None:
        return {"type": "none"}
    where = f"world '{world.name}'"
    tree = _tree(world)
    if tree is None:
        return {"type": "constant", "color": rgb(world.color), "strength": 1.0}
    out = tree.get_output_node("CYCLES") or tree.get_output_node("ALL")
    if out is None:
        return {"type": "none"}
    volume = out.inputs.get("Volume")
    fog = _follow(volume)[0] if volume is not None else None
    if fog is not None:
        # Mist and god rays from a world volume (Volume Scatter, Principled Volume): Lamina
        # renders no participating medium outside layer stacks, so the scene renders clear air.
        notes.append(f"{where}: {label(fog)} → Volume output (world volumes are not rendered: ignored)")
    node, _ = _follow(out.inputs["Surface"])
    if node is None:
        return {"type": "none"}
    if node.bl_idname not in ("ShaderNodeBackground", "ShaderNodeEmission"):
        notes.append(f"{where}: {label(node)} (not supported: black world)")
        return {"type": "none"}
    strength_sock = node.inputs["Strength"]
    if strength_sock.is_linked:
        notes.append(f"{where}: {node.name}.Strength is connected (value used)")
    strength = float(strength_sock.default_value)
    colour_sock = node.inputs["Color"]
    src, _ = _follow(colour_sock)
    if src is None:
        return {"type": "constant", "color": rgb(colour_sock.default_value), "strength": strength}
    if src.bl_idname == "ShaderNodeTexEnvironment" and src.image is not None:
        if src.projection != "EQUIRECTANGULAR":
            notes.append(f"{where}: {src.name} uses {src.projection.lower()} projection (read as equirectangular)")
        tex = images.texture(src.image)
        if tex is None:
            return {"type": "constant", "color": rgb(colour_sock.default_value), "strength": strength}
        entry = {"type": "environment", "file": tex["texture"], "strength": strength,
                 "colorspace": tex.get("colorspace", "auto")}
        rotation = _mapping_rotation(src, where, notes)
        if rotation is not None:
            entry["to_world"] = rotation
        return entry
    notes.append(f"{where}: {label(src)} → {node.name}.Color (not supported: colour value used)")
    return {"type": "constant", "color": rgb(colour_sock.default_value), "strength": strength}


def _mapping_rotation(env_node, where: str, notes: list[str]):
    """The rotation of a Mapping node feeding the Environment Texture, as a 4×4 to_world.

    A Mapping node (type Point or Vector) rotates the lookup direction d ↦ R·d, which turns the
    image by R⁻¹ in the world: to_world = R⁻¹ = Rᵀ (docs/lights.md, verified there against
    Cycles). Type Texture applies the inverse transform. Location and scale do not apply."""
    vec = env_node.inputs["Vector"]
    src, _ = _follow(vec)
    if src is None:
        return None
    if src.bl_idname != "ShaderNodeMapping":
        notes.append(f"{where}: {label(src)} → {env_node.name}.Vector (not supported: ignored)")
        return None
    if src.vector_type not in ("POINT", "TEXTURE", "VECTOR"):
        notes.append(f"{where}: {src.name} type {src.vector_type} (ignored)")
        return None
    from mathutils import Euler
    rot_sock = src.inputs.get("Rotation")
    if rot_sock is None or rot_sock.is_linked:
        return None
    r = Euler(rot_sock.default_value, "XYZ").to_matrix()
    if src.vector_type == "TEXTURE":
        r = r.inverted()       # a Texture mapping applies the inverse transform
    return matrix_rows(r.transposed().to_4x4())
