"""Bake Procedural Textures: Cycles bakes what feeds a material's inputs into images Lamina renders.

For every input that the node translator cannot read (anything but an Image Texture: Noise,
Voronoi, Checker, Math chains, Color Ramps...) — the inputs it lists in ``bakeable`` — the nodes
upstream of the input are routed into a temporary Emission shader and baked (Cycles, *Emit*, one
sample: the nodes are evaluated at each texel's centre) over the UV map of one object that uses
the material, into a float image packed in the .blend (``Lamina bake: material / node / input``).
export/baked.py records it; the export then uses the image as long as those nodes are unchanged.

Texture coordinates other than UV (Generated, Object: a procedural texture's default) depend on
the object: baked on the first object using the material, the image is right for that object and
approximate for others sharing the material (reported).
"""
from __future__ import annotations

import bpy
from bpy.props import IntProperty, StringProperty

from ..export import baked
from ..export.images import ImageExporter
from ..export.nodes import NodeTranslator

IMAGE_PREFIX = "Lamina bake: "


def bakeable_inputs(material) -> list:
    """(node, input name) of the inputs the export would read from a procedural source."""
    notes: list[str] = []
    translator = NodeTranslator(ImageExporter(None, False, notes), notes)
    translator.material(material)
    seen, out = set(), []
    for node, name in translator.bakeable:
        if (node.name, name) not in seen:
            seen.add((node.name, name))
            out.append((node, name))
    return out


def _users(scene, material) -> list:
    """Mesh objects of the scene rendering ``material``, those with a UV map first."""
    objs = [o for o in scene.objects if o.type == "MESH" and not o.hide_render
            and any(slot.material == material for slot in o.material_slots)]
    return sorted(objs, key=lambda o: (len(o.data.uv_layers) == 0, o.name))


def _bake_object(scene, obj, material):
    """A temporary copy of ``obj`` whose only material is ``material`` and whose only faces are
    those that use it (so the bake writes no other material's texels), with the original's
    texture space (Generated coordinates stay those of the original)."""
    mesh = obj.data.copy()
    slot = next(i for i, s in enumerate(obj.material_slots) if s.material == material)
    if len(obj.material_slots) > 1:
        import bmesh
        bm = bmesh.new()
        bm.from_mesh(mesh)
        bmesh.ops.delete(bm, geom=[f for f in bm.faces if f.material_index != slot], context="FACES")
        for f in bm.faces:
            f.material_index = 0
        bm.to_mesh(mesh)
        bm.free()
    mesh.use_auto_texspace = False
    mesh.texspace_location = obj.data.texspace_location
    mesh.texspace_size = obj.data.texspace_size
    mesh.materials.clear()
    mesh.materials.append(material)
    tmp = obj.copy()
    tmp.data = mesh
    tmp.name = "Lamina bake object"
    for s in tmp.material_slots:
        s.link = "DATA"
    scene.collection.objects.link(tmp)
    return tmp


def bake_input(context, material, node, input_name: str, obj, resolution: int):
    """Bake what feeds ``node.inputs[input_name]`` on ``obj``'s UV map; returns the image."""
    scene = context.scene
    tree = material.node_tree
    link = next(l for l in node.inputs[input_name].links if l.is_valid and not l.is_muted)
    source = link.from_socket
    name = f"{IMAGE_PREFIX}{material.name} / {node.name} / {input_name}"
    image = bpy.data.images.get(name)
    if image is not None and (tuple(image.size) != (resolution, resolution) or not image.is_float):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, resolution, resolution, alpha=False, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"     # the values as baked (linear data)
    output = tree.get_output_node("CYCLES") or tree.get_output_node("ALL")
    surface = output.inputs["Surface"]
    previous = [l.from_socket for l in surface.links]
    emit = tree.nodes.new("ShaderNodeEmission")
    holder = tree.nodes.new("ShaderNodeTexImage")
    holder.image = image
    active = tree.nodes.active
    tmp = None
    saved = (scene.render.engine, scene.cycles.samples, scene.cycles.use_denoising,
             scene.render.bake.margin, scene.render.bake.use_clear)
    try:
        tree.links.new(source, emit.inputs["Color"])
        emit.inputs["Strength"].default_value = 1.0
        tree.links.new(emit.outputs["Emission"], surface)
        tree.nodes.active = holder
        tmp = _bake_object(scene, obj, material)
        scene.render.engine = "CYCLES"
        scene.cycles.samples = 1
        scene.cycles.use_denoising = False
        scene.render.bake.margin = max(2, resolution // 64)
        scene.render.bake.use_clear = True
        with context.temp_override(active_object=tmp, object=tmp, selected_objects=[tmp],
                                   selected_editable_objects=[tmp]):
            bpy.ops.object.bake(type="EMIT", target="IMAGE_TEXTURES", use_clear=True,
                                margin=scene.render.bake.margin)
    finally:
        tree.nodes.remove(emit)
        tree.nodes.remove(holder)
        for s in previous:
            tree.links.new(s, surface)
        tree.nodes.active = active
        if tmp is not None:
            mesh = tmp.data
            bpy.data.objects.remove(tmp)
            bpy.data.meshes.remove(mesh)
        (scene.render.engine, scene.cycles.samples, scene.cycles.use_denoising,
         scene.render.bake.margin, scene.render.bake.use_clear) = saved
    image.pack()
    baked.record(material, node, input_name, image, obj)
    return image


def scene_materials(scene) -> list:
    """The materials of the scene's mesh objects, each once."""
    return list(dict.fromkeys(s.material for o in scene.objects if o.type == "MESH"
                              for s in o.material_slots if s.material is not None))


def bake_materials(context, materials, resolution: int, only_missing: bool = False):
    """Bake every bakeable input of ``materials`` (stacks have none); with ``only_missing`` only
    the inputs without an up-to-date baked image (never baked, or changed since). Returns (inputs
    baked, problems: one line each, naming the material, node and input)."""
    scene = context.scene
    done, problems = 0, []
    for material in materials:
        if getattr(material, "lamina", None) is not None and material.lamina.use_stack:
            continue
        inputs = bakeable_inputs(material)
        if only_missing:
            inputs = [(node, name) for node, name in inputs if baked.lookup(material, node, name)[0] is None]
        if not inputs:
            continue
        users = _users(scene, material)
        if not users or len(users[0].data.uv_layers) == 0:
            problems.append(f"material '{material.name}': no object of the scene with a UV map uses it")
            continue
        if len(users) > 1:
            problems.append(f"material '{material.name}': baked on '{users[0].name}' (also used by "
                            f"{len(users) - 1} other object(s): right for them only with UV coordinates)")
        for node, name in inputs:
            try:
                bake_input(context, material, node, name, users[0], resolution)
                done += 1
            except RuntimeError as exc:
                problems.append(f"material '{material.name}', {node.name}.{name}: {exc}")
    return done, problems


class LAMINA_OT_bake_procedurals(bpy.types.Operator):
    bl_idname = "lamina.bake_procedurals"
    bl_label = "Bake Procedural Textures"
    bl_description = ("Bake the procedural textures and node chains feeding this material's inputs "
                      "(Noise, Voronoi, Math...) into images over the UV map, which Lamina renders; "
                      "bake again after changing them")
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(name="Material", default="",
                             description="The material to bake (empty: every material of the scene)")
    resolution: IntProperty(name="Resolution", default=1024, min=16, max=8192,
                            description="Width and height of each baked image, in pixels")

    def execute(self, context):
        if self.material:
            materials = [bpy.data.materials.get(self.material)]
            if materials[0] is None:
                self.report({"ERROR"}, f"Lamina: no material '{self.material}'")
                return {"CANCELLED"}
        else:
            materials = scene_materials(context.scene)
        done, problems = bake_materials(context, materials, self.resolution)
        if problems:
            self.report({"WARNING"}, "Lamina: " + "; ".join(problems))
        self.report({"INFO"}, f"Lamina: baked {done} input(s)")
        return {"FINISHED"} if done or not problems else {"CANCELLED"}


CLASSES = (LAMINA_OT_bake_procedurals,)
register, unregister = bpy.utils.register_classes_factory(CLASSES)
