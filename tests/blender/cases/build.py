"""Scene building blocks for the bpy cases (data API only: fast and context-free)."""
from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Euler, Matrix, Vector


def scene():
    sc = bpy.context.scene
    sc.render.engine = "LAMINA"
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 64, 48, 100
    # The tests compare rendered images with statistical references: the render as rendered, not
    # denoised (on by default for artists; tests/blender/test_denoise.py turns it on).
    sc.lamina.use_denoising = False
    return sc


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def camera(name="Camera", location=(0.0, -6.0, 1.5), target=(0.0, 0.0, 0.5), lens=50.0):
    cam = bpy.data.cameras.new(name)
    cam.lens = lens
    obj = link(bpy.data.objects.new(name, cam))
    obj.location = location
    direction = Vector(target) - Vector(location)
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.camera = obj
    bpy.context.view_layer.update()
    return obj


def mesh_object(name, verts, faces, material=None, location=(0, 0, 0), uv=True):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    if uv:
        layer = me.uv_layers.new(name="UVMap")
        co = np.array(verts, dtype=np.float64)
        span = np.maximum(np.ptp(co, axis=0), 1e-9)
        loop_verts = np.empty(len(me.loops), np.int32)
        me.loops.foreach_get("vertex_index", loop_verts)
        uvs = ((co[loop_verts] - co.min(axis=0)) / span)[:, :2].astype(np.float32)
        layer.uv.foreach_set("vector", uvs.ravel())
    me.update()
    obj = link(bpy.data.objects.new(name, me))
    obj.location = location
    if material is not None:
        me.materials.append(material)
    return obj


def plane(name="Plane", size=4.0, material=None, z=0.0):
    h = size / 2
    return mesh_object(name, [(-h, -h, z), (h, -h, z), (h, h, z), (-h, h, z)], [(0, 1, 2, 3)], material)


def uv_sphere(name="Sphere", radius=1.0, segments=24, rings=12, material=None, location=(0, 0, 1)):
    verts = [(0.0, 0.0, radius)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = 2 * math.pi * j / segments
            verts.append((radius * math.sin(theta) * math.cos(phi), radius * math.sin(theta) * math.sin(phi),
                          radius * math.cos(theta)))
    verts.append((0.0, 0.0, -radius))
    faces = []
    for j in range(segments):
        faces.append((0, 1 + j, 1 + (j + 1) % segments))
    for i in range(rings - 2):
        a, b = 1 + i * segments, 1 + (i + 1) * segments
        for j in range(segments):
            faces.append((a + j, b + j, b + (j + 1) % segments, a + (j + 1) % segments))
    last = len(verts) - 1
    base = 1 + (rings - 2) * segments
    for j in range(segments):
        faces.append((base + (j + 1) % segments, base + j, last))
    obj = mesh_object(name, verts, faces, material, location)
    for poly in obj.data.polygons:
        poly.use_smooth = True
    return obj


def light(name, kind, location=(0, 0, 4), rotation=(0, 0, 0), **props):
    data = bpy.data.lights.new(name, kind)
    for key, value in props.items():
        setattr(data, key, value)
    obj = link(bpy.data.objects.new(name, data))
    obj.location = location
    obj.rotation_euler = Euler(rotation)
    return obj


def diffuse_material(name, colour=(0.8, 0.8, 0.8)):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    bsdf = tree.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*colour, 1.0)
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def world_colour(colour=(0.05, 0.05, 0.05), strength=1.0):
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    if bg is None:
        out = world.node_tree.nodes.new("ShaderNodeOutputWorld")
        bg = world.node_tree.nodes.new("ShaderNodeBackground")
        world.node_tree.links.new(bg.outputs[0], out.inputs["Surface"])
    bg.inputs["Color"].default_value = (*colour, 1.0)
    bg.inputs["Strength"].default_value = strength
    bpy.context.scene.world = world
    return world


def reference_stack(material):
    """The project's reference 3-layer stack (issue 3) built in the layer-stack editor."""
    from lamina.addon.ops.stack import add_layer
    s = material.lamina
    s.layers.clear()
    top = add_layer(s, "DIELECTRIC", 0)
    top.ior, top.roughness, top.distribution = 1.5, math.sqrt(0.05), "BECKMANN"
    top.thickness, top.sigma_t, top.albedo = 1.0, 0.5, (0.5, 0.7, 0.95)
    top.phase, top.flake_stddev, top.flake_orientation = "MICROFLAKE", 0.05, (0.5, 0.5, 0.0)
    mid = add_layer(s, "DIELECTRIC", 1)
    mid.ior, mid.roughness = 1.2, math.sqrt(0.01)
    mid.thickness, mid.sigma_t, mid.albedo = 1.0, 0.5, (0.5, 0.95, 0.5)
    mid.phase, mid.flake_stddev, mid.flake_orientation = "MICROFLAKE", 0.05, (0.5, -0.5, 0.0)
    bottom = add_layer(s, "CONDUCTOR", 2)
    bottom.metal, bottom.roughness = "Cu", math.sqrt(0.05)
    s.use_stack = True
    return material


def matrix_list(m):
    return [list(row) for row in Matrix(m)]
