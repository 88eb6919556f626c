"""A Cycles job (``convert.prepare``) → a Blender scene, inside the bpy child process only.

This module imports bpy; nothing in backend/ or the rest of the benchmark imports it (the parent
talks to ``cycles_child.py`` over a pipe). It supports exactly what ``convert.py`` lets through.

**The settings made equal** (also listed in docs/benchmarks.md; every number comes from the job,
i.e. from the Lamina scene dict):

* resolution, 100 %; the pixel filter: the same type and width (``convert.cycles_filter``), which
  mean the same filter in both since Lamina follows Cycles' ``filter_table`` (Blackman-Harris
  ``filter_width`` w spans ±w pixels; this benchmark found that Lamina's used to span ±w/2);
* ``max_bounces`` = the scene's, and the per-type limits (diffuse, glossy, transmission) raised to
  the same number, because Lamina has only the total; volume bounces 0 (no volumes);
* Russian roulette from the same surface: Cycles applies roulette at a surface whose bounce count
  (the camera hit is bounce 0) exceeds its kernel's ``min_bounce``, which is ``min_light_bounces``
  **+ 1** (src/scene/integrator.cpp: "plus one so that a bounce of 0 indicates no global
  illumination"); Lamina at a surface whose index (the camera hit is 0) is ≥ ``rr_depth``. Hence
  ``min_light_bounces`` = ``rr_depth`` − 2 (until issue 17's diagnosis this was ``rr_depth`` − 1,
  which started Cycles' roulette one surface later than Lamina's). Both use the survival
  probability min(1, √max(throughput)), decided after the emission the ray found;
* clamping: the scene's ``clamp`` as Cycles' ``sample_clamp_indirect`` (Lamina clamps what the
  vertices after the camera hit add, never the first hit's light: ``sample_clamp_direct`` 0);
  off (0) in every scene but "everyday" and "presets", which use Cycles' default indirect clamp
  10 as artists render (their sunlit glass and smooth coats make caustic fireflies that leave
  unclamped errors of a few hundred samples dominated by single paths); Filter Glossy off (``blur_glossy`` = 0; default 1), reflective and refractive
  caustics on (Lamina's paths are unbiased), denoising off, adaptive sampling off;
* microfacets: plain GGX (not Cycles' default Multiscatter GGX: Lamina is single-scattering) with
  Cycles' height-correlated Smith term (Lamina's ``"masking": "height-correlated"``, its default);
  roughness slider r = √α (Cycles squares it);
* conductors: Metallic BSDF in Physical Conductor mode with Lamina's (eta, k) per RGB channel;
* Principled materials (the scene's ``principled`` mapping, ``convert.principled_inputs``): a
  Principled BSDF node with exactly the scene's settings, plain GGX (Blender's default is
  Multiscatter GGX), every other input and option at Blender's defaults; the roughness sliders are
  the settings themselves (Lamina's side is the add-on's export of the same settings, or a preset);
* sun: a SUN light with the same strength (``energy``, W/m² of irradiance), angular diameter
  (``angle``), colour and ``matrix_world`` (both shine along the light's local −Z);
* area lights: one-sided (both), ``spread`` and ``normalize`` as given, visible to camera rays only
  where the scene says so (both default to hidden, Blender 5.0's default); lights do not occlude
  other rays in either renderer; point lights: the same radius, soft falloff off (Blender's default
  is on, Lamina's off: the scene value is used), the IES profile through an IES Texture node;
* geometry: the triangles and per-corner normals Lamina traces, flat where Lamina's normals are
  flat; Cycles' shadow-terminator geometry offset set to 0 (Lamina has none; Cycles' default 0.1
  moves shadow-ray origins on smooth meshes);
* threads: ``threads_mode`` FIXED with the requested count (all cores), CPU device.

Left at Cycles' defaults (its sampler as users run it; named in the report): the light tree, the
light threshold (0.01: shadow rays of weak light samples are terminated by roulette), the sampling
pattern (tabulated Sobol), the world's importance-sampling settings, persistent data off (each
render syncs the scene and builds its BVH, as each Lamina render loads the scene and builds embree).
"""
from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix


#: Deliberate mistakes for ``sensitivity.py`` only (``job["cycles_overrides"]``), never set by the
#: benchmark: they show what the agreement check catches.
_OVERRIDES: dict = {}


def _rough(alpha: float) -> float:
    """Lamina's α → Cycles' roughness slider (Cycles uses α = r²)."""
    if _OVERRIDES.get("roughness_is_alpha"):
        return float(alpha)
    return math.sqrt(max(float(alpha), 0.0))


def _rgb(v) -> tuple:
    if isinstance(v, (int, float)):
        return (float(v),) * 3
    return tuple(float(x) for x in v[:3])


def _ggx(node) -> None:
    node.distribution = _OVERRIDES.get("distribution", "GGX")


def _principled_node(tree, inputs: dict):
    """A Principled BSDF with ``inputs`` (node input name → number or RGB, from
    ``convert.principled_inputs``); everything else stays at Blender's defaults."""
    node = tree.nodes.new("ShaderNodeBsdfPrincipled")
    _ggx(node)
    for key, value in inputs.items():
        socket = node.inputs[key]
        socket.default_value = (*_rgb(value), 1.0) if socket.type == "RGBA" else float(value)
    return node


def _new_material(name: str, spec: dict | None, principled: dict | None = None):
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    if principled is not None:
        node = _principled_node(tree, principled)
        tree.links.new(node.outputs[0], out.inputs["Surface"])
        return mat
    kind = spec["type"]
    if kind == "diffuse":
        node = tree.nodes.new("ShaderNodeBsdfDiffuse")
        node.inputs["Color"].default_value = (*_rgb(spec.get("color", 0.8)), 1.0)
        node.inputs["Roughness"].default_value = 0.0          # Lambert (Oren-Nayar off)
    elif kind == "conductor":
        node = tree.nodes.new("ShaderNodeBsdfMetallic")
        node.fresnel_type = "PHYSICAL_CONDUCTOR"
        _ggx(node)
        node.inputs["IOR"].default_value = _rgb(spec["eta"])
        node.inputs["Extinction"].default_value = _rgb(spec["k"])
        node.inputs["Roughness"].default_value = _rough(spec.get("roughness", 0.1))
    elif kind == "dielectric":
        node = tree.nodes.new("ShaderNodeBsdfGlass")
        _ggx(node)
        node.inputs["IOR"].default_value = float(spec.get("ior", 1.5))
        node.inputs["Roughness"].default_value = _rough(spec.get("roughness", 0.0))
        node.inputs["Color"].default_value = (*_rgb(spec.get("transmission_color", 1.0)), 1.0)
    elif kind == "layered":
        # Coat over a Lambertian body (convert.coat_over_body): Principled with Coat, its base's
        # own specular layer switched off (Specular IOR Level 0) because Lamina's body is bare.
        coat, body = spec["interfaces"]
        node = tree.nodes.new("ShaderNodeBsdfPrincipled")
        _ggx(node)
        node.inputs["Base Color"].default_value = (*_rgb(body.get("color", 0.8)), 1.0)
        node.inputs["Metallic"].default_value = 0.0
        node.inputs["Diffuse Roughness"].default_value = 0.0
        node.inputs["Specular IOR Level"].default_value = 0.0
        node.inputs["Coat Weight"].default_value = 1.0
        node.inputs["Coat IOR"].default_value = float(coat.get("ior", 1.5))
        node.inputs["Coat Roughness"].default_value = _rough(coat.get("roughness", 0.0))
        node.inputs["Coat Tint"].default_value = (1.0, 1.0, 1.0, 1.0)
    else:  # convert.check_material refuses anything else
        raise ValueError(f"material {name}: {kind}")
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def _camera(sc, cam_spec: dict, width: int, height: int):
    frame = np.asarray(cam_spec["frame"], dtype=np.float64)     # tr, br, bl, tl at z < 0
    d = -frame[0, 2]
    hw, hh = frame[0, 0] / d, frame[0, 1] / d
    if not np.allclose(frame / d, [[hw, hh, -1], [hw, -hh, -1], [-hw, -hh, -1], [-hw, hh, -1]], atol=1e-9):
        raise ValueError("only centred frames (no lens shift) are converted")
    cam = bpy.data.cameras.new("camera")
    cam.type = "PERSP"
    cam.sensor_fit = "HORIZONTAL"
    cam.sensor_width = 36.0
    cam.lens = 18.0 / hw                                      # tan(half horizontal FOV) = hw
    cam.clip_start = float(cam_spec.get("clip_start", 1e-3)) or 1e-3
    cam.clip_end = float(cam_spec.get("clip_end", 1e5)) if math.isfinite(cam_spec.get("clip_end", 1e5)) else 1e5
    obj = bpy.data.objects.new("camera", cam)
    sc.collection.objects.link(obj)
    obj.matrix_world = Matrix(cam_spec["to_world"])
    sc.camera = obj
    bpy.context.view_layer.update()
    # Check: Blender's own image-plane corners, normalised to z = −1, are the description's.
    got = np.array([tuple(v) for v in cam.view_frame(scene=sc)], dtype=np.float64)
    got = got / -got[:, 2:3]
    want = frame / d
    return float(np.abs(got - want).max()), hh / hw * width / height


def _lights(sc, specs: list) -> None:
    for i, spec in enumerate(specs):
        kind = spec["type"]
        light = bpy.data.lights.new(f"light {i}", kind.upper())
        # Blender's one strength field: W for point and area lights, W/m² of irradiance for a sun.
        light.energy = float(spec["strength"] if kind == "sun" else spec["power"])
        light.color = _rgb(spec.get("color", 1.0))
        if kind == "sun":
            light.angle = math.radians(float(spec.get("angle", 0.0)))     # both: the full angular diameter
        elif kind == "area":
            light.shape = spec.get("shape", "square").upper()
            light.size = float(spec.get("size", 1.0))
            light.size_y = float(spec.get("size_y", spec.get("size", 1.0)))
            light.normalize = bool(spec.get("normalize", True))
            light.spread = math.radians(float(spec.get("spread", 180.0)))
        else:
            light.shadow_soft_size = float(spec.get("radius", 0.0))
            light.use_soft_falloff = bool(spec.get("soft_falloff", False))
            if "ies" in spec:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", DeprecationWarning)
                    light.use_nodes = True
                tree = light.node_tree
                emission = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeEmission")
                ies = tree.nodes.new("ShaderNodeTexIES")
                ies.mode = "EXTERNAL"
                ies.filepath = str(Path(spec["ies"]["file"]).resolve())
                tree.links.new(ies.outputs["Fac"], emission.inputs["Strength"])
        obj = bpy.data.objects.new(f"light {i}", light)
        sc.collection.objects.link(obj)
        obj.matrix_world = Matrix(spec["to_world"])
        obj.visible_camera = bool(spec.get("visible_camera", False))


def _world(sc, spec: dict) -> None:
    world = bpy.data.worlds.new("world")
    sc.world = world
    bg = world.node_tree.nodes["Background"]
    if spec.get("type", "none") == "constant":
        bg.inputs["Color"].default_value = (*_rgb(spec.get("color", 1.0)), 1.0)
        bg.inputs["Strength"].default_value = float(spec.get("strength", 1.0))
    else:
        bg.inputs["Strength"].default_value = 0.0


def _objects(sc, objects: list, geometry, materials: dict, principled: dict) -> int:
    made = {}
    triangles = 0
    for o in objects:
        pos = geometry[f"o{o['index']}_pos"].astype(np.float64)            # (T, 3, 3) world space
        nrm = geometry.get(f"o{o['index']}_nrm")
        slot = geometry[f"o{o['index']}_slot"]
        t = pos.shape[0]
        triangles += t
        me = bpy.data.meshes.new(o["name"])
        me.from_pydata(pos.reshape(-1, 3), [], np.arange(3 * t).reshape(t, 3))
        for name in o["materials"]:
            if name not in made:
                made[name] = _new_material(name, materials.get(name), principled.get(name))
            me.materials.append(made[name])
        me.polygons.foreach_set("material_index", slot.astype(np.int32))
        flat = True
        if nrm is not None:
            e = np.cross(pos[:, 1] - pos[:, 0], pos[:, 2] - pos[:, 0])
            e /= np.linalg.norm(e, axis=1, keepdims=True)
            flat = bool(np.all(np.abs(nrm.astype(np.float64) - e[:, None, :]).max() < 1e-5))
        if not flat:
            # Smooth faces with Lamina's per-corner normals as custom normals (loop i = corner i).
            me.polygons.foreach_set("use_smooth", np.ones(t, bool))
            me.normals_split_custom_set(nrm.reshape(-1, 3).astype(np.float64).tolist())
        else:
            me.polygons.foreach_set("use_smooth", np.zeros(t, bool))
        me.update()
        obj = bpy.data.objects.new(o["name"], me)
        obj.visible_camera = bool(o.get("visible_camera", True))
        obj.shadow_terminator_geometry_offset = 0.0
        obj.shadow_terminator_shading_offset = 0.0
        sc.collection.objects.link(obj)
    return triangles


def settings(sc, render: dict, threads: int) -> dict:
    """The render settings made equal (see the module docstring). Returns what was set and
    Cycles' own defaults that were kept, for the report."""
    c = sc.cycles
    c.device = "CPU"
    c.use_denoising = False
    c.use_adaptive_sampling = False
    bounces = int(render.get("max_bounces", 12))
    c.max_bounces = bounces
    c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.volume_bounces = 0
    c.min_light_bounces = max(int(render.get("rr_depth", 3)) - 2, 0)
    # Lamina's "clamp" is Cycles' indirect clamp (kernels/integrator.py _clamped: the sum of RGB of
    # what each vertex after the camera hit gathers); light at the first hit is never clamped.
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = float(render.get("clamp", 0.0))
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.use_animated_seed = False
    sc.render.threads_mode = "FIXED"
    sc.render.threads = threads
    sc.render.use_persistent_data = False
    sc.render.use_compositing = False
    sc.render.use_sequencer = False
    return {"kept": {"use_light_tree": bool(c.use_light_tree),
                     "light_sampling_threshold": round(float(c.light_sampling_threshold), 4),
                     "sampling_pattern": str(c.sampling_pattern),
                     "use_guiding": bool(c.use_guiding),
                     "world_sampling_method": str(sc.world.cycles.sampling_method) if sc.world else None},
            "set": {"max_bounces": bounces, "diffuse/glossy/transmission_bounces": bounces,
                    "min_light_bounces": c.min_light_bounces, "clamp": c.sample_clamp_indirect,
                    "blur_glossy": 0.0, "caustics": True, "threads": threads,
                    "filter": f"{c.pixel_filter_type} {c.filter_width:g}px"}}


def build(job_path: Path, threads: int) -> dict:
    """Build the scene of ``job.json`` in an empty Blender; returns checks for the report."""
    job = json.loads(Path(job_path).read_text(encoding="utf-8"))
    geometry = dict(np.load(Path(job_path).with_name("geometry.npz")))
    _OVERRIDES.clear()
    _OVERRIDES.update(job.get("cycles_overrides", {}))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    film = job["film"]
    sc.render.resolution_x, sc.render.resolution_y = int(film["width"]), int(film["height"])
    sc.render.resolution_percentage = 100
    sc.cycles.pixel_filter_type, sc.cycles.filter_width = job["cycles_filter"]     # convert.cycles_filter
    if "filter_width" in _OVERRIDES:
        sc.cycles.filter_width = float(_OVERRIDES["filter_width"])
    img = sc.render.image_settings
    img.file_format = "OPEN_EXR"
    img.color_depth = "32"
    img.color_mode = "RGB"
    img.exr_codec = "NONE"
    _world(sc, job.get("world", {}))
    frame_err, aspect = _camera(sc, job["camera"], sc.render.resolution_x, sc.render.resolution_y)
    _lights(sc, job.get("lights", []))
    tris = _objects(sc, job["objects"], geometry, job.get("materials", {}), job.get("principled", {}))
    info = settings(sc, job.get("render", {}), threads)
    info.update({"camera_frame_error": frame_err, "pixel_aspect": aspect, "triangles": tris,
                 "blender": bpy.app.version_string})
    return info


def render(path: Path, spp: int, seed: int):
    """One render to ``path`` (EXR). The caller reads the pixels and times the call."""
    sc = bpy.context.scene
    sc.cycles.samples = int(spp)
    sc.cycles.seed = int(seed)
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
