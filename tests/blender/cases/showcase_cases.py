"""The showcase .blend (run inside bpy by tests/blender/test_showcase_blend.py)."""
from __future__ import annotations

import os
from pathlib import Path

import bpy

PACKAGE = os.environ.get("LAMINA_TEST_PACKAGE", "lamina")


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
            "links": {m.name: link.state(m) for m in bpy.data.materials}}
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
