"""Cycles parity cases (run inside Blender by tests/blender/test_principled_parity.py).

The same scene is rendered by Cycles and by Lamina: Principled BSDF spheres in a row (one per
combination), other node materials, emission and light linking scenes. Both renderers use
every limit matched (no clamping, no filter-glossy, no denoising, no adaptive sampling, the same
bounce limit for every kind of bounce).
"""
from __future__ import annotations

import time

import numpy as np
from pathlib import Path

import bpy

from . import build

# name → Principled inputs (Blender socket names)
PRINCIPLED = {
    "default grey": {},
    "red, rough": {"Base Color": (0.8, 0.1, 0.05, 1), "Roughness": 0.8},
    "blue, smooth, IOR 2": {"Base Color": (0.1, 0.3, 0.9, 1), "Roughness": 0.15, "IOR": 2.0},
    "coat": {"Base Color": (0.2, 0.6, 0.2, 1), "Coat Weight": 1.0, "Coat Roughness": 0.1},
    "metallic 0.3": {"Base Color": (0.9, 0.6, 0.2, 1), "Metallic": 0.3, "Roughness": 0.4},
    "transmission 0.5": {"Base Color": (0.8, 0.8, 0.8, 1), "Transmission Weight": 0.5, "Roughness": 0.2},
    "gold": {"Base Color": (1.0, 0.77, 0.34, 1), "Metallic": 1.0, "Roughness": 0.3},
    "IOR level, tint": {"Base Color": (0.5, 0.5, 0.5, 1), "Specular IOR Level": 0.8,
                        "Specular Tint": (1.0, 0.6, 0.3, 1), "Roughness": 0.35},
    "mix shader": None,        # not a Principled BSDF: _mix_material
}
CELL = 24          # pixels per sphere
FLOOR_TURN = 0.0
SPACING = 2.4      # metres between sphere centres


def _principled(name, inputs):
    mat = bpy.data.materials.new(name)
    node = mat.node_tree.nodes["Principled BSDF"]
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return mat


def _mix_material(name):
    """A Mix Shader (Fac 0.4) of a red Diffuse BSDF and a Glossy BSDF (roughness 0.3)."""
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.4
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.7, 0.15, 0.1, 1.0)
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Roughness"].default_value = 0.3
    tree.links.new(diffuse.outputs[0], mix.inputs[1])
    tree.links.new(glossy.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def _match_cycles(sc, spp, bounces, threads=2):
    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    cy.samples = spp
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.light_sampling_threshold = 0.0
    cy.blur_glossy = 0.0
    cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = bounces
    cy.transparent_max_bounces = bounces
    cy.seed = 1
    cy.filter_width = 1.5
    sc.render.threads_mode = "FIXED"
    sc.render.threads = threads


def _render_both(sc, tmp, name, spp, bounces, lamina_spp=None):
    from .engine_cases import _render_to
    out = {}
    _match_cycles(sc, spp, bounces)
    path = Path(tmp) / f"{name}_cycles.exr"
    out["cycles_error"], out["cycles_seconds"] = _render_to(sc, path, multilayer=False)
    out["cycles"] = str(path)
    sc.render.engine = "LAMINA"
    sc.lamina.samples = lamina_spp or spp
    sc.lamina.max_bounces = bounces
    sc.lamina.rr_depth = 64
    sc.lamina.workers = 2
    path = Path(tmp) / f"{name}_lamina.exr"
    t0 = time.perf_counter()
    out["lamina_error"], out["lamina_seconds"] = _render_to(sc, path, multilayer=False)
    out["lamina"] = str(path)
    return out


def principled_spheres(tmp, spp=256, bounces=6):
    """One sphere per Principled combination, in a row, under a grey-blue world, a sun and an
    area light; no floor (each sphere's region holds only that sphere and the background)."""
    sc = build.scene()
    n = len(PRINCIPLED)
    sc.render.resolution_x, sc.render.resolution_y = CELL * n, CELL
    cam = bpy.data.cameras.new("cam")
    cam.type = "ORTHO"
    cam.ortho_scale = SPACING * n
    co = build.link(bpy.data.objects.new("cam", cam))
    co.location = (SPACING * (n - 1) / 2, -10.0, 0.0)
    co.rotation_euler = (1.5707963, 0.0, 0.0)
    sc.camera = co
    for i, (name, inputs) in enumerate(PRINCIPLED.items()):
        mat = _mix_material(name) if inputs is None else _principled(name, inputs)
        build.uv_sphere(name=f"S{i}", material=mat, segments=64, rings=32,
                        location=(SPACING * i, 0.0, 0.0))
    build.light("Sun", "SUN", (0, 0, 5), (0.9, 0.0, 0.5), energy=2.0, angle=0.05)
    build.light("Panel", "AREA", (SPACING * n / 2, -4.0, 4.0), (0.8, 0.0, 0.0), energy=1500.0,
                shape="RECTANGLE", size=6.0, size_y=2.0)
    build.world_colour((0.3, 0.35, 0.45), 1.0)
    out = _render_both(sc, tmp, "principled", spp, bounces)
    out["names"] = list(PRINCIPLED)
    out["cell"] = CELL
    return out


def _emission_material(name, strength, one_sided_cycles=False):
    """An Emission shader; for Cycles' one-sided emitter a Mix Shader picks a black emission on
    back faces (Geometry > Backfacing), Cycles having no one-sided option of its own."""
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    emit = tree.nodes.new("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = strength
    emit.inputs["Color"].default_value = (1.0, 0.9, 0.7, 1.0)
    if not one_sided_cycles:
        tree.links.new(emit.outputs[0], out.inputs["Surface"])
        return mat
    black = tree.nodes.new("ShaderNodeEmission")
    black.inputs["Strength"].default_value = 0.0
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(geometry.outputs["Backfacing"], mix.inputs["Fac"])
    tree.links.new(emit.outputs[0], mix.inputs[1])
    tree.links.new(black.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def emission_sides(tmp, spp=256, bounces=3, all_two=False):
    """Two emissive panels above a grey floor, one two-sided and one front-only, each tilted so
    the camera sees its back while its front lights the floor; a third, front-only, faces the
    camera. Cycles' one-sided emitters are Mix Shader + Backfacing; Lamina's the material's
    Emit From = Front Side."""
    import math
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = 72, 36
    build.camera(location=(0.0, -7.0, 4.0), target=(0.0, 0.0, 0.5), lens=35)
    floor = build.plane(size=10, material=build.diffuse_material("Floor", (0.6, 0.6, 0.6)))
    floor.rotation_euler = (0.0, 0.0, FLOOR_TURN)
    build.world_colour((0.02, 0.02, 0.02), 1.0)
    panels = []
    for i, (name, one_sided, tilt) in enumerate((("Two", False, 2.4), ("Front", True, -2.4),
                                                 ("Facing", True, 0.9))):
        obj = build.plane(f"Panel{name}", size=1.2)
        obj.location = (-2.5 + 2.5 * i, 0.0, 1.2)
        obj.rotation_euler = (tilt, 0.0, 0.0)
        one_sided = one_sided and not all_two
        cyc = _emission_material(f"{name}Cycles", 6.0, one_sided_cycles=one_sided)
        lam = _emission_material(f"{name}Lamina", 6.0)
        if one_sided:
            lam.lamina.emission_sides = "FRONT"
        obj.data.materials.append(cyc)
        panels.append((obj, cyc, lam))
    from .engine_cases import _render_to
    out = {}
    _match_cycles(sc, spp, bounces)
    path = Path(tmp) / "emission_cycles.exr"
    out["cycles_error"], out["cycles_seconds"] = _render_to(sc, path, multilayer=False)
    out["cycles"] = str(path)
    for obj, _, lam in panels:
        obj.data.materials[0] = lam
    sc.render.engine = "LAMINA"
    sc.lamina.samples = spp
    sc.lamina.max_bounces = bounces
    sc.lamina.rr_depth = 64
    sc.lamina.workers = 2
    path = Path(tmp) / "emission_lamina.exr"
    out["lamina_error"], out["lamina_seconds"] = _render_to(sc, path, multilayer=False)
    out["lamina"] = str(path)
    return out


# name → (tangent-space normal of the map, Normal Map strength); None: no map
NORMAL_PLANES = {"flat": None, "tilted +x 25°": ((0.4226, 0.0, 0.9063), 1.0),
                 "tilted +y 30°, strength 0.6": ((0.0, 0.5, 0.8660), 0.6)}


def _normal_mapped_material(name, normal, strength):
    """A grey Diffuse BSDF whose Normal comes from a Normal Map node (tangent space) reading a
    2 × 2 Non-Color float image of one normal."""
    mat = build.diffuse_material(name, (0.6, 0.6, 0.6))
    if normal is None:
        return mat
    tree = mat.node_tree
    image = bpy.data.images.new(f"{name}Normal", 2, 2, alpha=True, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    rgb = [(c + 1.0) / 2.0 for c in normal]
    image.pixels.foreach_set([*rgb, 1.0] * 4)
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    nmap = tree.nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Strength"].default_value = strength
    tree.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse")
    tree.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


# Bump node planes: (ramp direction, Distance, Strength, Invert). Each plane (1.8 m, UVs [0, 1]²)
# reads a 16 × 16 float height image rising by 1/16 per texel along u or v, so ∂h/∂u = 1 and the
# surface gradient is 1/1.8 per metre: Distance 1.8·tan 25° tilts the normal by 25°.
BUMP_PLANES = {"flat": None, "ramp u, inverted (towards +x 25°)": ("u", 0.8394, 1.0, True),
               "ramp v, strength 0.6 (towards -y)": ("v", 1.0392, 0.6, False)}


def _bumped_material(name, spec):
    """A grey Diffuse BSDF whose Normal comes from a Bump node over a ramp height image."""
    mat = build.diffuse_material(name, (0.6, 0.6, 0.6))
    if spec is None:
        return mat
    along, distance, strength, invert = spec
    tree = mat.node_tree
    n = 16
    image = bpy.data.images.new(f"{name}Height", n, n, alpha=True, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    ramp = np.arange(n, dtype=np.float32) / n
    h = np.broadcast_to(ramp[None, :] if along == "u" else ramp[:, None], (n, n))   # rows bottom-up
    image.pixels.foreach_set(np.stack([h, h, h, np.ones_like(h)], -1).ravel())
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = "Linear"
    bump = tree.nodes.new("ShaderNodeBump")
    bump.invert = invert
    bump.inputs["Distance"].default_value = distance
    bump.inputs["Strength"].default_value = strength
    tree.links.new(tex.outputs["Color"], bump.inputs["Height"])
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfDiffuse")
    tree.links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


def _three_planes(tmp, name, materials, spp, bounces):
    """Three 1.8 m planes side by side with ``materials``, under a sun 40° from the zenith
    towards +x and a dark world, seen from above; rendered by Cycles and Lamina."""
    import math
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = 96, 32
    build.camera(location=(0.0, -0.5, 9.0), target=(0.0, 0.0, 0.0), lens=50)
    build.world_colour((0.02, 0.02, 0.02), 1.0)
    build.light("Sun", "SUN", location=(0, 0, 5), rotation=(0.0, math.radians(40.0), 0.0), energy=3.0,
                angle=0.0)
    for i, mat in enumerate(materials):
        obj = build.plane(f"Plane{i}", size=1.8, material=mat)
        obj.location = (-2.1 + 2.1 * i, 0.0, 0.0)
    return _render_both(sc, tmp, name, spp, bounces)


def bumped_planes(tmp, spp=64, bounces=2):
    """No bump, a height ramp along u inverted (the normal leans towards the sun: brighter) and
    one along v at strength 0.6 (sideways: darker)."""
    mats = [_bumped_material(f"B{i}", spec) for i, spec in enumerate(BUMP_PLANES.values())]
    out = _three_planes(tmp, "bump_planes", mats, spp, bounces)
    out["names"] = list(BUMP_PLANES)
    return out


def normal_mapped_planes(tmp, spp=64, bounces=2):
    """No map, a normal map tilted 25° towards +x (towards the sun: brighter), and one tilted 30°
    towards +y at strength 0.6 (the map's green channel; darker)."""
    mats = []
    for i, spec in enumerate(NORMAL_PLANES.values()):
        normal, strength = spec if spec is not None else (None, 1.0)
        mats.append(_normal_mapped_material(f"N{i}", normal, strength))
    out = _three_planes(tmp, "normal_planes", mats, spp, bounces)
    out["names"] = list(NORMAL_PLANES)
    return out


def motion_blurred_cube(tmp, spp=64, bounces=2):
    """A red cube sliding 0.5 m along x during the shutter (keyframes x = −1 at frame 4 and +1 at
    frame 6, linear; frame 5, shutter 0.5 centred), and rotating 20° about z, on a grey floor
    under a sun and a grey world; the camera looks at it from −y."""
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = 64, 48
    build.camera(location=(0.0, -6.0, 1.5), target=(0.0, 0.0, 0.5), lens=50)
    build.world_colour((0.3, 0.3, 0.3), 1.0)
    build.light("Sun", "SUN", location=(0, 0, 5), rotation=(0.5, 0.2, 0.0), energy=3.0, angle=0.0)
    build.plane("Floor", size=10.0, material=build.diffuse_material("FloorGrey", (0.5, 0.5, 0.5)))
    h = 0.5
    verts = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    cube = build.mesh_object("Cube", verts, faces, material=build.diffuse_material("Red", (0.8, 0.1, 0.1)),
                             location=(0.0, 0.0, 0.5))
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    cube.location.x, cube.rotation_euler.z = -1.0, -0.4
    cube.keyframe_insert("location", frame=4)
    cube.keyframe_insert("rotation_euler", frame=4)
    cube.location.x, cube.rotation_euler.z = 1.0, 0.4
    cube.keyframe_insert("location", frame=6)
    cube.keyframe_insert("rotation_euler", frame=6)
    sc.frame_set(5)
    sc.render.use_motion_blur = True
    sc.render.motion_blur_shutter = 0.5
    out = _render_both(sc, tmp, "motion", spp, bounces)
    import json

    from lamina.addon.export import export_scene
    exported = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / "motion_export",
                            frame_set=lambda f, sub: sc.frame_set(f, subframe=sub))
    doc = json.loads(exported.path.read_text())
    out["motion_steps"] = {o["name"]: len(o.get("motion", [])) for o in doc["objects"]}
    out["frame_after"] = (sc.frame_current, sc.frame_subframe)
    return out
