#!/usr/bin/env python3
"""Build showcase/showcase.blend from the showcase definition (tools/gen_showcase.py) with bpy.

    python tools/gen_showcase_blend.py [--output showcase/showcase.blend]   # needs the bpy module
    python tools/dev.py showcase --blend                                   # render it (tools/render_blend.py)

The .blend holds the same scene as showcase/showcase.json, built the way an artist would in
Blender with the Lamina add-on:
  * meshes: the scene's own meshes, loaded with the backend's mesh reader (the .npz lathe and
    torus meshes, and the built-in sphere/cube/rectangle shapes) → Blender meshes with the same
    triangles, per-corner UVs and custom normals (stored as float vectors: Blender ≥ 4.5 reads
    them, older versions fall back to smooth normals);
  * materials: the presets applied through the add-on (layer stacks linked to their preset, so
    they export exactly), plain diffuse stacks for the floor and the wall;
  * lights: a point light with the IES profile in a Cycles IES Texture node (the profile is
    stored in a Text data-block inside the .blend), a rectangular area light with Lamina's
    beam/cutoff directionality; the world a constant Background colour;
  * camera, film size, samples, bounces and seed as in the scene file.
Textures and presets are referenced relative to the .blend (nothing is packed), and the file is
saved compressed, so it stays small.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SHOWCASE = ROOT / "showcase"
sys.path.insert(0, str(ROOT))


def load_generator():
    spec = importlib.util.spec_from_file_location("gen_showcase", ROOT / "tools" / "gen_showcase.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def enable_addon():
    """Load this checkout's add-on (a symlink named ``lamina``, as the bpy tests do)."""
    import addon_utils
    dev = Path(tempfile.mkdtemp(prefix="lamina-dev-"))
    (dev / "lamina").symlink_to(ROOT, target_is_directory=True)
    sys.path.insert(0, str(dev))
    addon_utils.enable("lamina", default_set=True, handle_error=None)
    import lamina.addon.ops.presets as presets
    import lamina.addon.presets.convert as convert
    return presets, convert


def backend_mesh(entry: dict):
    """A scene-file mesh entry parsed by the backend (the exact triangles the renderer uses)."""
    from backend.geometry.mesh import parse_mesh
    from backend.scene.reader import LoadContext, Node
    return parse_mesh(Node(entry, "mesh", LoadContext(str(SHOWCASE / "showcase.json"), SHOWCASE)))


def blender_mesh(name: str, mesh):
    import bpy
    me = bpy.data.meshes.new(name)
    me.from_pydata(mesh.positions.astype(np.float64).tolist(), [], mesh.indices.tolist())
    nt = len(mesh.indices)
    if mesh.uvs is not None:
        layer = me.uv_layers.new(name="UVMap")
        layer.uv.foreach_set("vector", mesh.uvs.reshape(-1).astype(np.float32))
    me.polygons.foreach_set("use_smooth", np.ones(nt, dtype=bool))
    if mesh.normals is not None:
        # "Free" custom normals (a float3 corner attribute, Blender ≥ 4.5) keep the scene's
        # normals exactly; normals_split_custom_set() would quantise them to 16-bit angles.
        attr = me.attributes.new("custom_normal", "FLOAT_VECTOR", "CORNER")
        attr.data.foreach_set("vector", mesh.normals.reshape(-1).astype(np.float32))
    me.update()
    return me


def relative(path: Path, start: Path) -> str:
    import bpy
    return bpy.path.relpath(str(path), start=str(start))


def build(output: Path) -> dict:
    import bpy
    from mathutils import Matrix

    gen = load_generator()
    doc = gen.scene()
    presets_ops, convert = enable_addon()
    from backend.presets import find_preset

    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.name = "Showcase"
    sc.render.engine = "LAMINA"
    sc.render.resolution_x, sc.render.resolution_y = doc["film"]["width"], doc["film"]["height"]
    sc.render.resolution_percentage = 100
    sc.render.filepath = "//../out/showcase_blend_"
    sc.render.image_settings.file_format = "PNG"
    sc.view_settings.view_transform = "Standard"        # the backend's --png preview is plain sRGB
    r = doc["render"]
    sc.lamina.samples, sc.lamina.max_bounces, sc.lamina.seed = r["spp"], r["max_bounces"], r["seed"]

    # Camera: the scene's frame lies at distance 1 with half-width hw → lens = (sensor/2) / hw.
    cam_doc = doc["camera"]
    frame = np.array(cam_doc["frame"])
    half_width = float(np.abs(frame[:, 0]).max() / np.abs(frame[:, 2]).max())
    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit, cam.sensor_width = "HORIZONTAL", 36.0
    cam.lens = cam.sensor_width / 2.0 / half_width
    cam.clip_start, cam.clip_end = 0.01, 100.0
    cam_obj = bpy.data.objects.new("Camera", cam)
    sc.collection.objects.link(cam_obj)
    cam_obj.matrix_world = Matrix(cam_doc["to_world"])
    sc.camera = cam_obj

    # Materials: presets through the add-on; literal materials as (unlinked) stacks.
    materials = {}
    for key, value in doc["materials"].items():
        mat = bpy.data.materials.new(key)
        if isinstance(value, str):
            path = find_preset(value)
            presets_ops.apply_preset(mat, path)
            mat.lamina.preset_file = relative(path, output.parent)
        else:
            dropped = convert.material_from_json(mat, value, SHOWCASE, key)
            assert not dropped, dropped
            mat.diffuse_color = (*value["color"], 1.0)
        materials[key] = mat
    # What Cycles, EEVEE and Material Preview show for each stack (addon/ops/viewport_colour.py).
    import lamina.addon.ops.viewport_colour as viewport_colour
    for key, mat in materials.items():
        if not viewport_colour.update_now(mat):
            raise SystemExit(f"gen_showcase_blend: the viewport colour of '{key}' was not measured")

    meshes = {name: blender_mesh(name, backend_mesh(entry)) for name, entry in doc["meshes"].items()}
    for entry in doc["objects"]:
        obj = bpy.data.objects.new(entry["name"], meshes[entry["mesh"]])
        sc.collection.objects.link(obj)
        obj.matrix_world = Matrix(entry.get("to_world", np.eye(4).tolist()))
        while len(obj.data.materials) < len(entry["materials"]):
            obj.data.materials.append(None)
        for slot, key in zip(obj.material_slots, entry["materials"]):
            slot.link = "OBJECT"                      # floor and wall share the plane mesh
            slot.material = materials[key]

    for i, light_doc in enumerate(doc["lights"]):
        kind = light_doc["type"]
        if kind == "point":
            light = bpy.data.lights.new("IES Spot", "POINT")
            light.shadow_soft_size = float(light_doc.get("radius", 0.0))
            light.use_soft_falloff = bool(light_doc.get("soft_falloff", False))
            if "ies" in light_doc:
                ies_file = SHOWCASE / light_doc["ies"]["file"]
                text = bpy.data.texts.new(ies_file.name)
                text.from_string(ies_file.read_bytes().decode("latin-1"))   # LM-63 files are not UTF-8
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", DeprecationWarning)
                    light.use_nodes = True
                tree = light.node_tree
                emission = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeEmission")
                ies = tree.nodes.new("ShaderNodeTexIES")
                ies.mode, ies.ies = "INTERNAL", text
                ies.location = (emission.location.x - 220, emission.location.y)
                tree.links.new(ies.outputs["Fac"], emission.inputs["Strength"])
        elif kind == "area":
            light = bpy.data.lights.new("Soft Box", "AREA")
            light.shape = light_doc.get("shape", "square").upper()
            light.size = float(light_doc["size"])
            light.size_y = float(light_doc.get("size_y", light_doc["size"]))
            light.normalize = bool(light_doc.get("normalize", True))
            if "cutoff_angle" in light_doc:
                light.lamina.beam_mode = "CONE"
                light.lamina.cutoff_angle = math.radians(light_doc["cutoff_angle"])
                light.lamina.beam_width = math.radians(light_doc.get("beam_width", light_doc["cutoff_angle"]))
        else:
            raise SystemExit(f"gen_showcase_blend: light type {kind!r} is not handled")
        light.energy = float(light_doc["power"])
        light.color = light_doc.get("color", [1.0, 1.0, 1.0])
        obj = bpy.data.objects.new(light.name, light)
        sc.collection.objects.link(obj)
        obj.matrix_world = Matrix(light_doc["to_world"])
        obj.visible_camera = bool(light_doc.get("visible_camera", False))

    world_doc = doc["world"]
    world = bpy.data.worlds.new("World")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        world.use_nodes = True
    background = next(n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
    background.inputs["Color"].default_value = (*world_doc["color"], 1.0)
    background.inputs["Strength"].default_value = float(world_doc.get("strength", 1.0))
    world.color = world_doc["color"]
    sc.world = world

    for image in bpy.data.images:                    # the presets' textures, relative to the .blend
        image.filepath = relative(Path(bpy.path.abspath(image.filepath)), output.parent)

    output.parent.mkdir(parents=True, exist_ok=True)
    bpy.context.preferences.filepaths.save_version = 0      # no showcase.blend1 backup
    bpy.ops.wm.save_as_mainfile(filepath=str(output), compress=True, relative_remap=False)
    return {"objects": len(doc["objects"]), "materials": len(materials), "lights": len(doc["lights"]),
            "bytes": output.stat().st_size}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=SHOWCASE / "showcase.blend")
    args = parser.parse_args(argv)
    try:
        import bpy  # noqa: F401
    except ImportError:
        print("gen_showcase_blend: needs the bpy module (pip install -r requirements-dev.txt)", file=sys.stderr)
        return 2
    info = build(args.output.resolve())
    print(f"wrote {args.output} ({info['bytes'] / 1024:.0f} KiB: {info['objects']} objects, "
          f"{info['materials']} materials, {info['lights']} lights)")
    print(json.dumps(info))
    return 0


if __name__ == "__main__":
    sys.exit(main())
