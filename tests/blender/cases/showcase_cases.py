"""The showcase .blend (run inside bpy by tests/blender/test_showcase_blend.py)."""
from __future__ import annotations

import os
from pathlib import Path

import bpy

PACKAGE = os.environ.get("LAMINA_TEST_PACKAGE", "lamina")


def _viewport(material):
    """What Cycles and EEVEE render for ``material``: the BSDF feeding its active output."""
    tree = material.node_tree
    out = tree.get_output_node("CYCLES") if tree is not None else None
    links = out.inputs["Surface"].links if out is not None else []
    node = links[0].from_node if links else None
    if node is None or node.bl_idname != "ShaderNodeBsdfPrincipled":
        return {"output": out.name if out else None, "node": node.bl_idname if node else None}
    get = lambda *names: next(node.inputs[n].default_value for n in names if n in node.inputs)
    return {"output": out.name, "node": node.name, "base_color": list(get("Base Color"))[:3],
            "metallic": get("Metallic"), "roughness": get("Roughness"),
            "transmission": get("Transmission Weight", "Transmission"),
            "solid": list(material.diffuse_color)[:3]}


def showcase(tmp, blend, width, height, spp):
    """Export the .blend's scene as it is, then render it small through the LAMINA engine."""
    import importlib
    export_scene = importlib.import_module(f"{PACKAGE}.addon.export").export_scene
    link = importlib.import_module(f"{PACKAGE}.addon.export.preset_link")
    bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
    sc = bpy.context.scene
    exported = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / "export")
    info = {"scene": str(exported.path), "notes": exported.notes, "engine": sc.render.engine,
            "images": [[img.name, img.filepath, img.packed_file is not None] for img in bpy.data.images],
            "texts": [t.name for t in bpy.data.texts],
            "links": {m.name: link.state(m) for m in bpy.data.materials},
            "viewport": {m.name: _viewport(m) for m in bpy.data.materials}}
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = width, height, 100
    sc.lamina.samples, sc.lamina.workers = spp, 1
    sc.lamina.use_denoising = False        # compared with the scene file's render, as rendered
    out = Path(tmp) / "blend_render.exr"
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.filepath = str(out)
    sc.render.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    info["render"] = str(out)
    return info
