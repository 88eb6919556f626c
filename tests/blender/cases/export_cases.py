"""Export cases: run inside Blender by tests/blender/test_export.py."""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import bpy
import numpy as np

from . import build

IES = Path(__file__).resolve().parents[2] / "data" / "ies" / "erco_narrow10_lm95.ies"


def _export(tmp, name="scene"):
    from lamina.addon.export import export_scene
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return export_scene(depsgraph, Path(tmp) / name)


def reference_stack(tmp):
    sc = build.scene()
    build.camera()
    mat = build.reference_stack(bpy.data.materials.new("Reference"))
    build.uv_sphere(material=mat)
    result = _export(tmp, "reference")
    doc = json.loads(result.path.read_text())
    # The render settings' layered pdf as each choice of the panel exports it.
    from lamina.addon.export.scene import render_json
    pdf = {}
    for mode in ("LOBES", "APPROXIMATE", "STOCHASTIC"):
        sc.lamina.pdf_mode = mode
        pdf[mode] = render_json(sc).get("layered", {}).get("pdf")
    return {"material": doc["materials"]["Reference"], "notes": result.notes,
            "default_pdf_mode": type(sc.lamina).bl_rna.properties["pdf_mode"].default, "layered_pdf": pdf}


def every_phase_kind(tmp):
    """Each phase function of the layer's enum, with the panel's defaults, as the export writes it."""
    from lamina.addon.export.stack import medium_json
    build.scene()
    mat = build.reference_stack(bpy.data.materials.new("Phases"))
    layer = mat.lamina.layers[0]
    out = {}
    for item in layer.bl_rna.properties["phase"].enum_items:
        layer.phase = item.identifier
        out[item.identifier] = medium_json(layer, None)["phase"]
    return out


def full_scene(tmp):
    """Plane + sphere (3-layer stack) + every light type + world; instances, hidden, holdout."""
    sc = build.scene()
    cam = build.camera()
    floor_mat = build.diffuse_material("Floor", (0.5, 0.5, 0.5))
    floor = build.plane(material=floor_mat, size=6)
    stack = build.reference_stack(bpy.data.materials.new("Layered"))
    sphere = build.uv_sphere(material=stack)
    sphere.scale = (1.0, 1.0, 0.5)
    # Instances: a collection instanced three times shares one mesh.
    coll = bpy.data.collections.new("Props")
    cube = build.mesh_object("Cube", [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)],
                             [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)],
                             floor_mat)
    bpy.context.scene.collection.objects.unlink(cube)
    coll.objects.link(cube)
    instances = []
    for i in range(3):
        empty = build.link(bpy.data.objects.new(f"Inst{i}", None))
        empty.instance_type = "COLLECTION"
        empty.instance_collection = coll
        empty.location = (2.0 + i, 2.0, 0.0)
        instances.append(empty.name)
    hidden = build.plane("HiddenPlane", size=1, z=3.0)
    hidden.hide_render = True
    holdout = build.plane("HoldoutPlane", size=1, z=3.5)
    holdout.is_holdout = True
    # Subdivision is applied by the depsgraph: 8 quads → 32 triangles... on a cube: 6·4 quads.
    sub = build.mesh_object("SubCube", [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)],
                            [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)],
                            floor_mat, location=(-3, 2, 0))
    mod = sub.modifiers.new("Subdivision", "SUBSURF")
    mod.render_levels = 1
    mod.levels = 1

    point = build.light("Point", "POINT", (1, -1, 3), energy=100.0, shadow_soft_size=0.25)
    point.data.lamina.ies_mode = "FILE"
    point.data.lamina.ies_file = str(IES)
    spot = build.light("Spot", "SPOT", (-1, -1, 3), (0.3, 0, 0), energy=200.0, spot_size=math.radians(40),
                       spot_blend=0.2, color=(1.0, 0.5, 0.25))
    spot.data.exposure = 1.0
    sun = build.light("Sun", "SUN", (0, 0, 5), (0.5, 0.2, 0), energy=3.0, angle=math.radians(2))
    area = build.light("Area", "AREA", (0, 2, 3), (2.5, 0, 0), energy=50.0, shape="RECTANGLE",
                       size=0.5, size_y=0.25)
    area.scale = (2.0, 3.0, 1.0)
    area.data.lamina.beam_mode = "CONE"
    area.data.lamina.cutoff_angle = math.radians(40)
    area.data.lamina.beam_width = math.radians(20)
    area2 = build.light("AreaSpread", "AREA", (0, -2, 3), energy=20.0, shape="DISK", size=0.3)
    area2.data.spread = math.radians(30)
    build.world_colour((0.1, 0.2, 0.3), 0.5)
    cam.data.dof.use_dof = True
    cam.data.dof.focus_object = sphere
    cam.data.dof.aperture_fstop = 2.8
    cam.data.dof.aperture_blades = 6
    cam.data.lens = 35.0
    bpy.context.view_layer.update()
    focus = -(cam.matrix_world.normalized().inverted() @ sphere.matrix_world.translation).z

    t0 = time.perf_counter()
    result = _export(tmp, "full")
    seconds = time.perf_counter() - t0
    sub_eval = sub.evaluated_get(bpy.context.evaluated_depsgraph_get())
    info = {
        "path": str(result.path), "notes": result.notes, "stats": result.stats, "seconds": seconds,
        "matrices": {o.name: build.matrix_list(o.matrix_world) for o in
                     (floor, sphere, point, spot, sun, area, area2)},
        "instance_matrices": [build.matrix_list(bpy.data.objects[n].matrix_world) for n in instances],
        "subdivided_triangles": len(sub_eval.data.loop_triangles),
        "area_world_area": area.data.area(matrix_world=area.matrix_world) if hasattr(area.data, "area") else None,
        "camera_frame": [list(v) for v in cam.data.view_frame(scene=sc)],
        "focus_distance": focus,
        "ies_text": IES.read_text(errors="replace"),
    }
    return info


def mesh_arrays(tmp):
    """A mesh with a sharp edge, a UV map and two material slots, against a Python-loop reading."""
    build.scene()
    build.camera()
    a = build.diffuse_material("A")
    b = build.diffuse_material("B", (0.2, 0.3, 0.4))
    obj = build.mesh_object("Wedge", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 0.5, 1)],
                            [(0, 1, 2, 3), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)], a)
    obj.data.materials.append(b)
    for poly in obj.data.polygons:
        poly.use_smooth = True
        poly.material_index = 1 if poly.index % 2 else 0
    obj.data.edges[0].use_edge_sharp = True
    obj.data.update()
    result = _export(tmp, "mesh")
    doc = json.loads(result.path.read_text())
    mesh_file = result.path.parent / doc["meshes"]["Wedge"]["file"]
    arrays = {k: v.tolist() for k, v in np.load(mesh_file).items()}
    # Reference, the slow way: per loop triangle, through Python objects.
    me = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    me.calc_loop_triangles()
    ref = {"indices": [list(t.vertices) for t in me.loop_triangles],
           "material_indices": [t.material_index for t in me.loop_triangles],
           "normals": [[list(me.corner_normals[l].vector) for l in t.loops] for t in me.loop_triangles],
           "uvs": [[list(me.uv_layers.active.uv[l].vector) for l in t.loops] for t in me.loop_triangles],
           "positions": [list(v.co) for v in me.vertices],
           "domain": me.normals_domain}
    return {"arrays": arrays, "ref": ref, "slots": doc["objects"][0]["materials"]}


def node_materials(tmp):
    """Node-tree translation: Principled variants, Glass, Emission and unsupported nodes."""
    build.scene()
    build.camera()
    mats = {}

    def principled(name, **inputs):
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        node = mat.node_tree.nodes["Principled BSDF"]
        for key, value in inputs.items():
            node.inputs[key].default_value = value
        mats[name] = mat
        return mat, node

    principled("Plastic", **{"Base Color": (0.2, 0.4, 0.6, 1), "Roughness": 0.3, "IOR": 1.45})
    principled("Coated", **{"Base Color": (0.9, 0.1, 0.1, 1), "Coat Weight": 1.0, "Coat Roughness": 0.1,
                            "Coat IOR": 1.6})
    principled("Gold", **{"Base Color": (1.0, 0.766, 0.336, 1), "Metallic": 1.0, "Roughness": 0.2})
    principled("Glassy", **{"Transmission Weight": 1.0, "IOR": 1.33, "Roughness": 0.0})
    principled("Glow", **{"Emission Color": (1.0, 0.5, 0.25, 1), "Emission Strength": 4.0})
    mat, node = principled("Textured")
    image = bpy.data.images.new("checker", 8, 8, alpha=False, float_buffer=False)
    image.generated_type = "COLOR_GRID"
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    mat.node_tree.links.new(tex.outputs["Color"], node.inputs["Base Color"])
    rough = mat.node_tree.nodes.new("ShaderNodeTexImage")
    rough.image = image
    mat.node_tree.links.new(rough.outputs["Color"], node.inputs["Roughness"])
    mat, node = principled("NormalMapped", **{"Base Color": (0.5, 0.5, 0.5, 1)})
    bumps = bpy.data.images.new("bumps", 8, 8, alpha=False, float_buffer=False)
    bumps.colorspace_settings.name = "Non-Color"
    nmap = mat.node_tree.nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Strength"].default_value = 0.7
    ntex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    ntex.image = bumps
    mat.node_tree.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    mat.node_tree.links.new(nmap.outputs["Normal"], node.inputs["Normal"])
    diffuse_mat = bpy.data.materials.new("DiffuseNormalMapped")
    diffuse_mat.use_nodes = True
    tree = diffuse_mat.node_tree
    dif = tree.nodes.new("ShaderNodeBsdfDiffuse")
    tree.links.new(dif.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    nmap = tree.nodes.new("ShaderNodeNormalMap")
    ntex = tree.nodes.new("ShaderNodeTexImage")
    ntex.image = bumps
    tree.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    tree.links.new(nmap.outputs["Normal"], dif.inputs["Normal"])
    mats["DiffuseNormalMapped"] = diffuse_mat
    # A Bump node over a Normal Map, its Height from an image texture.
    mat, node = principled("Bumped", **{"Base Color": (0.5, 0.5, 0.5, 1)})
    bump = mat.node_tree.nodes.new("ShaderNodeBump")
    bump.invert = True
    bump.inputs["Distance"].default_value = 0.02
    bump.inputs["Strength"].default_value = 0.8
    htex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    htex.image = bumps
    mat.node_tree.links.new(htex.outputs["Color"], bump.inputs["Height"])
    nmap = mat.node_tree.nodes.new("ShaderNodeNormalMap")
    ntex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    ntex.image = bumps
    mat.node_tree.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    mat.node_tree.links.new(nmap.outputs["Normal"], bump.inputs["Normal"])
    mat.node_tree.links.new(bump.outputs["Normal"], node.inputs["Normal"])
    mat, node = principled("Unsupported")
    noise = mat.node_tree.nodes.new("ShaderNodeTexNoise")
    mat.node_tree.links.new(noise.outputs["Color"], node.inputs["Base Color"])
    node.inputs["Sheen Weight"].default_value = 0.5
    mix_mat = bpy.data.materials.new("Mixed")
    mix_mat.use_nodes = True
    tree = mix_mat.node_tree
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    mats["Mixed"] = mix_mat
    glass_mat = bpy.data.materials.new("GlassNode")
    glass_mat.use_nodes = True
    tree = glass_mat.node_tree
    glass = tree.nodes.new("ShaderNodeBsdfGlass")
    glass.inputs["IOR"].default_value = 1.5
    glass.inputs["Roughness"].default_value = 0.2
    glass.inputs["Color"].default_value = (0.9, 1.0, 0.9, 1)
    tree.links.new(glass.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    mats["GlassNode"] = glass_mat
    for i, (name, mat) in enumerate(mats.items()):
        build.plane(name, size=0.5, material=mat, z=0.1 * i)
    result = _export(tmp, "nodes")
    doc = json.loads(result.path.read_text())
    textures = {}
    for name in ("Textured",):
        base = doc["materials"][name]["interfaces"]
        for itf in base:
            for key in ("color", "roughness"):
                value = itf.get(key)
                if isinstance(value, dict):
                    path = result.path.parent / value["texture"]
                    textures[key] = {"exists": path.is_file(), "suffix": path.suffix,
                                     "header": path.read_bytes()[:2].decode("ascii", "replace")}
    return {"materials": doc["materials"], "warning": result.warning_text(), "notes": result.notes,
            "textures": textures}


def million_triangles(tmp):
    """Export time of a ~1M-triangle mesh (built with foreach_set: primitive ops are too slow)."""
    build.scene()
    build.camera()
    n = 725                                  # n² quads = 1,051,250 triangles
    xs, ys = np.meshgrid(np.linspace(-1, 1, n + 1), np.linspace(-1, 1, n + 1))
    verts = np.stack([xs.ravel(), ys.ravel(), 0.1 * np.sin(5 * xs.ravel())], 1).astype(np.float32)
    idx = np.arange((n + 1) * (n + 1)).reshape(n + 1, n + 1)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], -1).reshape(-1, 4)
    me = bpy.data.meshes.new("Big")
    me.vertices.add(len(verts))
    me.vertices.foreach_set("co", verts.ravel())
    me.loops.add(quads.size)
    me.loops.foreach_set("vertex_index", quads.ravel().astype(np.int32))
    me.polygons.add(len(quads))
    me.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    me.polygons.foreach_set("use_smooth", np.ones(len(quads), bool))
    me.uv_layers.new()
    me.update()
    build.link(bpy.data.objects.new("Big", me))
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    from lamina.addon.export import export_scene
    times = []
    for i in range(2):
        t0 = time.perf_counter()
        result = export_scene(depsgraph, Path(tmp) / f"big{i}")
        times.append(time.perf_counter() - t0)
    size = sum(p.stat().st_size for p in (Path(tmp) / "big0").rglob("*") if p.is_file())
    return {"seconds": times, "triangles": result.stats["triangles"], "bytes": size}


def world_and_images(tmp):
    """Environment Texture with a Mapping node; packed, external and generated images."""
    import math
    from mathutils import Euler
    build.scene()
    build.camera()
    png = Path(tmp) / "sky.png"
    gen = bpy.data.images.new("sky", 16, 8, alpha=False)
    gen.generated_color = (0.2, 0.4, 0.8, 1.0)
    gen.save(filepath=str(png))
    sky = bpy.data.images.load(str(png))
    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    tree = world.node_tree
    bg = tree.nodes["Background"]
    bg.inputs["Strength"].default_value = 2.0
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = sky
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(90))
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    bpy.context.scene.world = world
    # A packed image on a diffuse colour, via the layer stack.
    packed = bpy.data.images.load(str(png), check_existing=False)
    packed.name = "packed"
    packed.pack()
    mat = bpy.data.materials.new("Packed")
    from lamina.addon.ops.stack import add_layer
    layer = add_layer(mat.lamina, "DIFFUSE", 0)
    layer.color_texture = packed
    layer.color = (0.5, 1.0, 1.0)
    mat.lamina.use_stack = True
    build.plane(material=mat)
    from lamina.addon.export import export_scene
    result = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / "world", copy_textures=True)
    doc = json.loads(result.path.read_text())
    tex = doc["materials"]["Packed"]["color"]
    folder = result.path.parent
    return {"world": doc["world"], "texture": tex,
            "packed_bytes_equal": (folder / tex["texture"]).read_bytes() == png.read_bytes(),
            "world_file_exists": (folder / doc["world"]["file"]).is_file(),
            "rotation": build.matrix_list(Euler((0.0, 0.0, math.radians(90))).to_matrix().to_4x4()),
            "notes": result.notes}


def export_operator(tmp):
    """File > Export > Lamina Scene, one frame and an animation."""
    sc = build.scene()
    build.camera()
    obj = build.plane(material=build.diffuse_material("Grey"))
    obj.location = (0, 0, 0)
    obj.keyframe_insert("location", frame=1)
    obj.location = (0, 0, 2)
    obj.keyframe_insert("location", frame=3)
    sc.frame_start, sc.frame_end = 1, 3
    sc.frame_set(2)
    single = Path(tmp) / "op" / "shot.json"
    single.parent.mkdir(parents=True, exist_ok=True)
    status = list(bpy.ops.lamina.export_scene(filepath=str(single)))
    anim = Path(tmp) / "op_anim" / "shot.json"
    anim.parent.mkdir(parents=True, exist_ok=True)
    status_anim = list(bpy.ops.lamina.export_scene(filepath=str(anim), animation=True))
    frames = sorted(p.name for p in anim.parent.glob("shot_*.json"))
    heights = [json.loads((anim.parent / f).read_text())["objects"][0]["to_world"][2][3] for f in frames]
    doc = json.loads(single.read_text())
    mesh_file = single.parent / doc["meshes"]["Plane"]["file"]
    first_bytes = mesh_file.read_bytes() if mesh_file.is_file() else b""
    # The same mesh exported again, an hour later as the clock says, gives the same bytes
    # (np.savez stamps no time): cluster renders send files by content hash (docs/cluster.md).
    import time as _time
    clock = _time.time
    _time.time = lambda: clock() + 3600.0
    try:
        bpy.ops.lamina.export_scene(filepath=str(single))
    finally:
        _time.time = clock
    return {"status": status, "status_anim": status_anim, "frames": frames, "heights": heights,
            "single_height": doc["objects"][0]["to_world"][2][3], "frame_after": sc.frame_current,
            "mesh_file_exists": mesh_file.is_file(),
            "mesh_bytes_stable": bool(first_bytes) and mesh_file.read_bytes() == first_bytes}


def render_settings(tmp):
    """The Render Properties as Blender holds them (defaults, then every field set to a value of
    its own) and the scene file's ``render`` the export writes for them."""
    from lamina.addon.export.scene import render_json
    from lamina.backend.render_settings import SETTINGS
    sc = build.scene()
    rna = type(sc.lamina).bl_rna.properties
    defaults = {st.name: render_json(sc)[st.name] for st in SETTINGS if st.property_name}
    props = {st.name: {"min": getattr(rna[st.property_name], "hard_min", None),
                       "max": getattr(rna[st.property_name], "hard_max", None),
                       "default": rna[st.property_name].default if st.kind is not str else
                       rna[st.property_name].default.lower(),
                       "description": rna[st.property_name].description}
             for st in SETTINGS if st.property_name}
    edited = {}
    for st in SETTINGS:
        if st.property_name is None:
            continue
        if st.kind is str:
            value = st.choices[-1][0].upper()
        elif st.kind is int:
            value = int(st.lo) + 3
        else:
            value = float(st.lo) + 0.125
        setattr(sc.lamina, st.property_name, value)
        edited[st.name] = render_json(sc)[st.name]
    sc.lamina.fail_on_missing_textures = True
    return {"defaults": defaults, "props": props, "edited": edited,
            "missing": render_json(sc)["missing_textures"]}
