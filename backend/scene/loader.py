"""Load and validate a scene description (docs/scene-format.md) into a renderable :class:`Scene`.

Everything a user can get wrong is reported as a SceneError naming the file and field; the
warnings (degenerate triangles dropped, texels sanitised, missing material slots...) are collected
in ``Scene.warnings`` for the CLI/add-on to show.
"""
from __future__ import annotations

from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SceneError
from ..geometry.accel import TriangleSoup
from ..geometry.mesh import Mesh, parse_mesh
from ..limits import MAX_COORDINATE, MAX_FILM_SIDE, film_memory_problem, short
from ..render_settings import SETTINGS, RenderSettings
from .inputs import record_inputs
from .links import CAMERA, LIGHT_FLAGS, OBJECT_FLAGS, SHADOW, build_links, parse_linking, parse_visibility
from .reader import MISSING_TEXTURES, LoadContext, Node, dispatch, path_problem, read_json

FORMAT = "lamina-scene"
VERSION = 1


@dataclass
class Scene:
    source: str
    width: int
    height: int
    pixel_filter: object
    crop: tuple[int, int, int, int] | None
    transparent: bool
    camera: object
    settings: RenderSettings
    materials: list
    material_names: list[str]
    soup: TriangleSoup
    lights: list                      # every light incl. mesh lights and the world
    world: object | None
    mesh_light: object | None
    warnings: list[str] = field(default_factory=list)
    center: np.ndarray = None
    radius: float = 1.0
    # The files and preset names the load read (scene/inputs.py): what a cluster render sends
    # to its workers. {"files": [absolute path, ...], "presets": {name: path}}.
    inputs: dict = field(default_factory=dict)
    # Data passes (backend/passes.py): the requested ones, and the offset the load subtracted
    # from every position (``rebased``; Position adds it back).
    passes: object = None
    origin: tuple = (0.0, 0.0, 0.0)
    # Cameras of named views (stereo / multi-view): the CLI's --view renders one of them.
    views: dict = field(default_factory=dict)
    # Ray visibility, light and shadow linking (scene/links.py); None: nothing restricted.
    links: object = None


def load_scene(path: str | Path) -> Scene:
    where = short(path, 300)
    problem = path_problem(str(path))
    if problem:
        raise SceneError(where, "", problem)
    path = Path(path)
    try:
        if not path.is_file():
            raise SceneError(where, "", "scene file not found")
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(where, "", f"cannot read file: {short(exc, 200)}") from None
    except MemoryError:
        raise SceneError(where, "", "cannot read file: not enough memory") from None
    data = read_json(text, where)
    return load_scene_data(data, where, path.parent)


def known(names, most: int = 12) -> str:
    """A list of names for an error message: at most ``most``, each shortened."""
    names = list(names)
    text = ", ".join(short(n, 40) for n in names[:most]) or "none"
    return text + (f", … ({len(names)} in all)" if len(names) > most else "")


REBASE_ABOVE = 1000.0   # world units: a camera farther than this from the origin rebases the scene


def rebase_offset(data) -> np.ndarray | None:
    """The offset ``rebased`` subtracts: the camera position if it is more than REBASE_ABOVE
    units from the origin, else None (also for malformed input, left for validation)."""
    try:
        cam = np.asarray(data["camera"]["to_world"], dtype=np.float64)
        if cam.shape != (4, 4):
            return None
        offset = cam[:3, 3].copy()
        if not np.all(np.isfinite(offset)) or np.linalg.norm(offset) <= REBASE_ABOVE:
            return None
        return offset
    except (KeyError, TypeError, ValueError, IndexError):
        return None


def rebased(data, offset: np.ndarray | None = None):
    """The scene moved so that the camera sits at the origin, if it is more than REBASE_ABOVE
    units away from it (a georeferenced or large-world scene); else ``data`` itself.

    Geometry is traced in float32 (embree): 10⁵ units from the origin a float32 step is 8 mm,
    and a 2-unit scene rendered there came out 0.7 % darker (≈ 3σ). Rendering does not depend on
    where the origin is — textures use UVs, the environment and sun only directions — so
    subtracting one offset from the translation of every ``to_world`` (camera, objects, lights)
    changes nothing but precision. The offset is exact in float64 and the document is not
    modified (a shallow copy is returned). Malformed input is left for validation to report.

    ``offset`` given: subtract that one instead (a viewport session keeps the offset it chose
    when the scene arrived, so later camera moves do not move the world)."""
    if offset is None:
        offset = rebase_offset(data)
        if offset is None:
            return data
    try:
        return rebase_sections(data, offset)
    except (KeyError, TypeError, ValueError, IndexError):
        return data


def rebase_sections(data: dict, offset: np.ndarray) -> dict:
    """``data`` with ``offset`` subtracted from the translation of the camera, every object and
    every light (the sections that are present; a shallow copy). A malformed transform raises
    ValueError or TypeError."""
    def moved(node, default_identity: bool):
        if not isinstance(node, dict) or ("to_world" not in node and not default_identity):
            return node
        m = np.asarray(node.get("to_world", np.eye(4).tolist()), dtype=np.float64)
        if m.shape != (4, 4):
            raise ValueError("to_world is not a 4x4 matrix")
        m = m.copy()
        m[:3, 3] -= offset
        out = {**node, "to_world": m.tolist()}
        if isinstance(node.get("motion"), list):          # motion blur: every step moves too
            steps = [np.array(k, dtype=np.float64) for k in node["motion"]]
            if any(k.shape != (4, 4) for k in steps):
                raise ValueError("motion holds a matrix that is not 4x4")
            for k in steps:
                k[:3, 3] -= offset
            out["motion"] = [k.tolist() for k in steps]
        return out

    out = dict(data)
    if "camera" in data:
        out["camera"] = moved(data["camera"], False)
    if isinstance(data.get("objects"), list):
        out["objects"] = [moved(o, True) for o in data["objects"]]
    if isinstance(data.get("lights"), list):
        out["lights"] = [moved(l, False) for l in data["lights"]]
    return out


def load_scene_data(data, where: str = "<scene>", base_dir: Path | None = None) -> Scene:
    recorder = record_inputs()
    if recorder is None:
        return _load_scene_data(data, where, base_dir)
    with recorder:
        scene = _load_scene_data(data, where, base_dir)
    scene.inputs = {"files": list(recorder.files), "presets": dict(recorder.presets)}
    return scene


def _load_scene_data(data, where: str, base_dir: Path | None) -> Scene:
    offset = rebase_offset(data)
    data = rebased(data, offset) if offset is not None else data
    ctx = LoadContext(where, base_dir)
    root = Node(data, "", ctx)
    root.require_object()
    check_header(root)

    settings = parse_settings(root.optional_child("render"), ctx)
    width, height, pixel_filter, crop, transparent = parse_film(root.child("film"))
    from ..camera import parse_camera
    camera = parse_camera(root.child("camera"))
    views = parse_views(root.optional_child("views"), offset)
    from ..passes import parse_passes
    passes = parse_passes(root.optional_child("passes"))

    materials, names = parse_materials(root.optional_child("materials"))
    meshes = parse_meshes(root.optional_child("meshes"))
    lights_node = root.optional_child("lights")
    announce_heavy_scene(root.optional_child("objects"), meshes, lights_node, ctx)
    soup = flatten_objects(root.optional_child("objects"), meshes, materials, names, ctx)
    lights = parse_lights(lights_node)
    light_nodes = lights_node.items() if lights_node is not None else []   # for the warnings
    world = parse_world(root.optional_child("world"))
    root.finish()
    scene = assemble_scene(ctx, width, height, pixel_filter, crop, transparent, camera, settings,
                           materials, names, soup, lights, world, light_nodes=light_nodes, root=root)
    scene.passes = passes
    scene.origin = tuple(float(v) for v in offset) if offset is not None else (0.0, 0.0, 0.0)
    scene.views = views
    return scene


#: Where a warning about a heavy scene goes the moment it is known (render_one sets it, so the
#: user reads it before the minutes of loading, not after); None: into the scene's warnings.
HEAVY_SCENE_NOTICE: ContextVar = ContextVar("heavy_scene_notice", default=None)


def announce_heavy_scene(objects: Node | None, meshes: dict, lights: Node | None, ctx: LoadContext) -> None:
    """Warn, before flattening and the lights' tables, about a scene that will take several GiB
    (a million lights, a small compressed mesh instanced into tens of millions of triangles)."""
    from ..limits import heavy_scene_message
    items = objects.items() if objects is not None else []
    triangles = sum(meshes[o.value["mesh"]].triangle_count for o in items
                    if isinstance(o.value, dict) and isinstance(o.value.get("mesh"), str) and o.value["mesh"] in meshes)
    count = len(lights.value) if lights is not None and isinstance(lights.value, list) else 0
    message = heavy_scene_message(triangles, count)
    if message is None:
        return
    notice = HEAVY_SCENE_NOTICE.get()
    if notice is not None:
        notice(f"{ctx.where}: {message}")
    else:
        ctx.warn("", message)


def parse_views(node: Node | None, offset) -> dict:
    """``views``: view name → camera (stereo eyes, multi-view cameras), moved by the same
    rebase offset as the scene's camera."""
    if node is None:
        return {}
    from ..camera import parse_camera
    views = {}
    for name, vnode in node.entries():
        if name.startswith("_"):
            continue
        if offset is not None and isinstance(vnode.value, dict):
            vnode = Node(rebase_sections({"camera": vnode.value}, offset)["camera"], vnode.path, vnode.ctx)
        views[name] = parse_camera(vnode)
    return views


def check_header(root: Node) -> None:
    fmt = root.string("format")
    if fmt != FORMAT:
        raise root.fail(f"expected {FORMAT!r}, got {short(fmt)!r}", "format")
    version = root.integer("version")
    if version != VERSION:
        raise root.fail(f"unsupported scene version {version} (this Lamina reads version {VERSION})", "version")


def assemble_scene(ctx: LoadContext, width: int, height: int, pixel_filter, crop, transparent: bool, camera,
                   settings: RenderSettings, materials: list, names: list[str], soup: TriangleSoup,
                   lights: list, world, bounds: tuple[np.ndarray, float] | None = None,
                   light_nodes: list | None = None, root: Node | None = None) -> Scene:
    """The renderable scene from its parsed sections: the mesh light of emissive triangles, every
    light prepared with the scene bounds (computed unless ``bounds`` is given), the warnings (those
    naming a light or the render options when their nodes, ``light_nodes`` and ``root``, are given)."""
    mesh_light = build_mesh_light(soup, materials)
    all_lights = list(lights) + ([mesh_light] if mesh_light is not None else []) + ([world] if world is not None else [])
    center, radius = bounds if bounds is not None else scene_bounds(soup, lights, camera)
    for light in all_lights:
        light.prepare(center, radius)
    scene = Scene(ctx.where, width, height, pixel_filter, crop, transparent, camera, settings, materials, names,
                  soup, all_lights, world, mesh_light, ctx.warnings, center, radius)
    scene.links = build_links(soup, list(lights), ctx)
    if light_nodes is not None:
        warn_dark_lights(lights, light_nodes, ctx)
    if root is not None:
        warn_unused_layered_options(root, materials, ctx)
    if not all_lights:
        ctx.warn("", "the scene has no lights and no world: the image will be black")
    elif all(light.power() <= 0.0 for light in all_lights):
        # power(): the luminance flux used for light selection, 0 only for black or zero-strength
        # emitters (luminance weights are positive).
        ctx.warn("", f"every light in the scene emits nothing ({len(all_lights)} checked): "
                     f"the image will be black")
    return scene


# --------------------------------------------------------------------------- sections

def parse_settings(node: Node | None, ctx: LoadContext) -> RenderSettings:
    s = RenderSettings()
    if node is None:
        ctx.cache["layered_defaults"] = {}
        ctx.missing_textures = MISSING_TEXTURES.get() or s.missing_textures
        return s
    for st in SETTINGS:                  # each field as backend/render_settings.py defines it
        if st.kind is int:
            value = node.integer(st.name, st.default, lo=st.lo, hi=st.hi)
        elif st.kind is float:
            value = node.number(st.name, st.default, lo=st.lo, hi=st.hi)
        else:
            value = node.string(st.name, st.default, choices=tuple(c[0] for c in st.choices))
        setattr(s, st.name, value)
    s.missing_textures = MISSING_TEXTURES.get() or s.missing_textures
    ctx.missing_textures = s.missing_textures
    layered = node.optional_child("layered")
    ctx.cache["layered_defaults"] = dict(layered.require_object().value) if layered is not None else {}
    if layered is not None:
        # Checked here, whether or not a layered material uses them: a typo or a bad value is
        # an error even in a scene without layered materials (which gets a warning instead).
        from ..layered.material import parse_options
        parse_options(Node({}, "render.layered", ctx), layered)
        layered.finish()
    node.finish()
    return s


def parse_film(node: Node):
    from ..film import parse_filter
    width = node.integer("width", lo=1, hi=MAX_FILM_SIDE)
    height = node.integer("height", lo=1, hi=MAX_FILM_SIDE)
    problem = film_memory_problem(width, height)
    if problem:
        raise node.fail(problem)
    pixel_filter = parse_filter(node.optional_child("filter"))
    crop = None
    if node.has("crop"):
        c = node.vector("crop", 4)
        x0, y0, x1, y1 = (int(round(v)) for v in c)
        if not (0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height):
            raise node.fail(f"expected 0 <= x0 < x1 <= {width} and 0 <= y0 < y1 <= {height}, got {c.tolist()}", "crop")
        crop = (x0, y0, x1, y1)
    transparent = node.boolean("transparent", False)
    node.finish()
    return width, height, pixel_filter, crop, transparent


def parse_material(node: Node):
    """A material object, or a string naming a preset."""
    from ..materials import load_all
    if isinstance(node.value, str):
        from ..presets import resolve_preset  # the preset library resolves names
        return resolve_preset(node.value, node)
    # "emission_sides" (any material): "both" (default, as Cycles) or "front" (the side the
    # triangles' counter-clockwise winding faces). Read here so every material type takes it,
    # as "pass_index" (the Material Index pass, backend/passes.py).
    sides = node.string("emission_sides", "both", choices=("both", "front")) if isinstance(node.value, dict) else "both"
    from ..passes import MAX_PASS_INDEX
    pass_index = node.integer("pass_index", 0, lo=0, hi=MAX_PASS_INDEX) if isinstance(node.value, dict) else 0
    # "normal" / "normal_strength" (any material): a normal map of the whole material
    # (materials/normal.py; Blender's Normal Map node); a stack's interfaces take their own.
    detail = None
    if isinstance(node.value, dict):
        from ..materials.normal import parse_detail
        detail = parse_detail(node)
    material = dispatch(node, load_all())
    if pass_index:
        material.pass_index = pass_index
    if detail is not None:
        if detail.normal is not None:
            material.normal_map = detail.normal
            material.normal_strength = detail.strength
        if detail.bump is not None:
            material.bump = detail.bump
    if sides == "front":
        if getattr(material, "emission", None) is None:
            node.ctx.warn(node.sub("emission_sides"), "the material emits nothing: ignored")
        else:
            material.emission_front_only = True
    return material


def parse_materials(node: Node | None):
    materials, names = [], []
    if node is None:
        return materials, names
    for name, mnode in node.entries():
        materials.append(parse_material(mnode))
        names.append(name)
    from ..materials.mix import flatten
    flatten(materials, names)        # a Mix/Add Shader's components become rows of their own
    return materials, names


def parse_meshes(node: Node | None) -> dict[str, Mesh]:
    """The named meshes; refused as soon as the triangles so far cannot fit in memory."""
    meshes = {}
    if node is not None:
        from ..limits import geometry_memory_problem
        held = 0
        for name, mnode in node.entries():
            meshes[name] = parse_mesh(mnode)
            held += meshes[name].triangle_count
            problem = geometry_memory_problem(held)
            if problem:
                raise mnode.fail(problem.replace("the objects hold", "the meshes so far hold")
                                 .replace(" (instances counted)", ""))
    return meshes


def parse_lights(node: Node | None) -> list:
    from ..lights import load_all as load_lights
    light_parsers, _ = load_lights()
    lights = []
    for lnode in (node.items() if node is not None else []):
        lnode.require_object()
        # Ray visibility and linking (scene/links.py) are common to every lamp type.
        vis = parse_visibility(lnode, LIGHT_FLAGS, CAMERA | SHADOW)
        receivers, blockers = parse_linking(lnode, blockers=True)
        light = dispatch(lnode, light_parsers)
        light.ray_vis, light.receivers, light.blockers = vis, receivers, blockers
        lights.append(light)
    return lights


def parse_world(node: Node | None):
    """The world light, or None (no world, or ``{"type": "none"}``)."""
    if node is None:
        return None
    node.require_object()
    if node.value.get("type") == "none":
        node.ignore("type")
        node.finish()
        return None
    from ..lights import load_all as load_lights
    _, world_parsers = load_lights()
    return dispatch(node, world_parsers)


def default_material():
    from ..materials import load_all
    ctx = LoadContext("<default material>")
    return dispatch(Node({"type": "diffuse", "color": [0.8, 0.8, 0.8]}, "", ctx), load_all())


def flatten_objects(node: Node | None, meshes: dict[str, Mesh], materials: list, names: list[str],
                    ctx: LoadContext) -> TriangleSoup:
    verts, norms, uvs, mats, objs, cam, hold = [], [], [], [], [], [], []
    object_pass: list[float] = []          # each object's pass index (Object Index pass)
    object_uv: list[bool] = []             # whether its mesh has a UV map (UV pass)
    obj_names, obj_vis, obj_receivers = [], [], []      # per object (scene/links.py)
    any_normals = any_uvs = False
    moving: list = []                      # per object: [(corners, normals) per motion step] or None
    motion_steps = None
    default_index = None
    items = node.items() if node is not None else []
    from ..limits import geometry_memory_problem
    total = sum(meshes[o.value["mesh"]].triangle_count for o in items
                if isinstance(o.value, dict) and isinstance(o.value.get("mesh"), str) and o.value["mesh"] in meshes)
    problem = geometry_memory_problem(total)
    if problem:
        raise node.fail(problem)             # before flattening allocates it
    for oi, onode in enumerate(items):
        onode.require_object()
        onode.string("name", f"object {oi}")
        mesh_name = onode.string("mesh")
        if mesh_name not in meshes:
            raise onode.fail(f"unknown mesh {short(mesh_name)!r} (known: {known(sorted(meshes))})", "mesh")
        mesh = meshes[mesh_name]
        m = onode.matrix4("to_world", np.eye(4).tolist())
        motion = onode.motion()
        visible = onode.boolean("visible_camera", True)
        holdout = onode.boolean("holdout", False)
        from ..passes import MAX_PASS_INDEX
        object_pass.append(float(onode.integer("pass_index", 0, lo=0, hi=MAX_PASS_INDEX)))
        obj_names.append(onode.value.get("name", f"object {oi}"))
        obj_vis.append(parse_visibility(onode, OBJECT_FLAGS, CAMERA if visible else 0))
        obj_receivers.append(parse_linking(onode, blockers=False)[0])
        slot_names = []
        slots_node = onode.optional_child("materials")
        if slots_node is not None:
            for snode in slots_node.items():
                if not isinstance(snode.value, str):
                    from .reader import _describe
                    raise snode.fail(f"expected a material name, got {_describe(snode.value)}")
                slot_names.append(snode.value)
        onode.finish()
        slot_index = []
        for si, sname in enumerate(slot_names):
            if sname in names:
                slot_index.append(names.index(sname))
            else:
                raise ctx.error(f"objects[{oi}].materials[{si}]",
                                f"unknown material {short(sname)!r} (known: {known(names)})")
        tri_slots = mesh.material_indices if mesh.material_indices is not None else np.zeros(mesh.triangle_count, np.int32)
        if len(slot_index) == 0 or (tri_slots.size and tri_slots.max() >= len(slot_index)):
            if default_index is None:
                materials.append(default_material())
                names.append("<default>")
                default_index = len(materials) - 1
            missing = int((tri_slots >= len(slot_index)).sum())
            ctx.warn(f"objects[{oi}]", f"{missing} triangle(s) use a material slot that is not set: grey diffuse used")
        lut = np.array(slot_index + [default_index if default_index is not None else 0], dtype=np.int32)
        tri_mat = lut[np.minimum(tri_slots, len(slot_index))]

        v, nrm, mirrored = _placed(mesh, m, onode, mesh_name, "to_world")
        if nrm is not None:
            any_normals = True
        uv = mesh.uvs
        object_uv.append(uv is not None)
        if uv is not None:
            any_uvs = True
            if mirrored:
                uv = uv[:, [0, 2, 1]]
        moving.append(None)
        if motion is not None:
            if any(getattr(materials[k], "emission", None) is not None for k in np.unique(tri_mat)):
                ctx.warn(f"objects[{oi}].motion", "an emitting object is not motion-blurred (its "
                                                  "light is sampled where it is at the frame): ignored")
            elif motion_steps is not None and len(motion) != motion_steps:
                raise onode.fail(f"{len(motion)} motion steps, but another object has {motion_steps}: "
                                 f"every moving object needs the same number", "motion")
            else:
                motion_steps = len(motion)
                steps = [_placed(mesh, mk, onode, mesh_name, f"motion[{k}]") for k, mk in enumerate(motion)]
                if any(st[2] != mirrored for st in steps):
                    raise onode.fail("the transform mirrors at some times and not at others", "motion")
                moving[-1] = [(st[0], st[1]) for st in steps]
        verts.append(v)
        norms.append(nrm)
        uvs.append(uv)
        mats.append(tri_mat)
        objs.append(np.full(mesh.triangle_count, oi, np.int32))
        cam.append(np.full(mesh.triangle_count, visible))
        hold.append(np.full(mesh.triangle_count, holdout))
    if not verts:
        empty = np.zeros((0, 3, 3), np.float32)
        soup = TriangleSoup(empty, None, None, np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros(0, bool))
        soup.object_pass, soup.object_uv = object_pass, object_uv
        soup.object_names, soup.object_vis, soup.object_receivers = obj_names, np.array(obj_vis, np.uint8), obj_receivers
        return soup
    # Moving objects' triangles last (geometry/embree_lib.py traces them at each ray's time).
    order = [k for k in range(len(verts)) if moving[k] is None] + [k for k in range(len(verts)) if moving[k]]
    verts, norms, uvs, mats, objs, cam, hold, moving = ([a[k] for k in order] for a in
                                                        (verts, norms, uvs, mats, objs, cam, hold, moving))
    vertices = np.concatenate(verts)
    normals = None
    if any_normals:
        normals = np.concatenate([n if n is not None else _flat_normals(v) for n, v in zip(norms, verts)]).astype(np.float32)
    uv_all = None
    if any_uvs:
        uv_all = np.concatenate([u if u is not None else np.zeros((v.shape[0], 3, 2), np.float32)
                                 for u, v in zip(uvs, verts)]).astype(np.float32)
    soup = TriangleSoup(vertices, normals, uv_all, np.concatenate(mats), np.concatenate(objs), np.concatenate(cam),
                        np.concatenate(hold))
    moved = [mv for mv in moving if mv]
    if moved:
        soup.motion = [np.concatenate([mv[k][0] for mv in moved]) for k in range(motion_steps)]
        if any_normals:
            soup.motion_normals = [np.concatenate([n if n is not None else _flat_normals(v) for v, n in
                                                   (mv[k] for mv in moved)]).astype(np.float32)
                                   for k in range(motion_steps)]
    soup.object_pass, soup.object_uv = object_pass, object_uv
    soup.object_names, soup.object_vis, soup.object_receivers = obj_names, np.array(obj_vis, np.uint8), obj_receivers
    return soup


def warn_dark_lights(lights: list, nodes: list, ctx: LoadContext) -> None:
    """One warning per light that is dark for sure, naming it (its ``_name`` from the add-on)
    and why: zero power or strength, a black colour, zero size, an all-zero IES table."""
    for light, node in zip(lights, nodes):
        try:
            power = float(light.power())
        except (ValueError, ArithmeticError):
            power = 0.0
        name = node.value.get("_name") if isinstance(node.value, dict) else None
        label = f" ({short(name)!r})" if isinstance(name, str) and name else ""
        if power >= FAINT_LIGHT_WATTS:
            continue
        if power > 0.0:
            # A denormal IES multiplier (1e-320) rendered a dark light without a word (issue 39).
            ctx.warn(node.path, f"light{label} emits only {power:.3g} W (below "
                                f"{FAINT_LIGHT_WATTS:g} W): it is practically dark; check its power, "
                                f"strength, colour or IES multiplier")
            continue
        why = dark_reason(light)
        ctx.warn(node.path, f"light{label} emits nothing ({why}): it is dark")


#: A light emitting less than this (in watts) is warned about as practically dark: a trillionth
#: of a small LED's power, far below anything a scene lights with.
FAINT_LIGHT_WATTS = 1e-12


def dark_reason(light) -> str:
    color = getattr(light, "color", None)
    amount = next((getattr(light, a) for a in ("watts", "strength") if hasattr(light, a)), None)
    if amount is not None and amount <= 0:
        return "power 0" if hasattr(light, "watts") else "strength 0"
    if color is not None and float(np.max(color)) <= 0:
        return "black colour"
    geo = getattr(light, "geo", None)
    if geo is not None and geo.area <= 0:
        return "size 0: zero area"
    profile = getattr(getattr(light, "profile", None), "profile", None)
    if profile is not None and getattr(profile, "flux", 1.0) <= 0:
        return "its IES table is zero everywhere"
    if profile is not None:
        return "its IES profile emits nothing inside the spot cone"
    return "zero emitted power"


def warn_unused_layered_options(root: Node, materials: list, ctx: LoadContext) -> None:
    """``render.layered`` sets options of layered stacks (two or more interfaces); say so when no
    material has one (the options were checked, but change nothing)."""
    render = root.value.get("render") if isinstance(root.value, dict) else None
    if not (isinstance(render, dict) and render.get("layered")):
        return
    if not any(getattr(m, "interfaces", None) is not None and len(m.interfaces) > 1 for m in materials):
        ctx.warn("render.layered", "no layered material with two or more interfaces in the scene "
                                   "uses these options: they change nothing")


def _placed(mesh: Mesh, m: np.ndarray, onode: Node, mesh_name: str, field: str):
    """(float32 world corners (T, 3, 3), float64 unit world normals per corner or None,
    mirrored) of ``mesh`` placed by ``m``; a mirroring matrix swaps two corners (CCW = front)."""
    p = mesh.positions.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    reach = float(np.max(np.abs(p))) if p.size else 0.0
    if not reach <= MAX_COORDINATE:
        raise onode.fail(f"mesh {short(mesh_name)!r} placed by this matrix reaches the coordinate "
                         f"{reach:.3g}; world coordinates must lie within ±{MAX_COORDINATE:g}", field)
    # Rounded to float32 (what embree traces) per vertex, before the corners are spread.
    v = p.astype(np.float32)[mesh.indices]
    nrm = None
    if mesh.normals is not None:
        nrm = _placed_normals(mesh.normals, np.linalg.inv(m[:3, :3]).T)
    mirrored = bool(np.linalg.det(m[:3, :3]) < 0)
    if mirrored:
        v = v[:, [0, 2, 1]]
        nrm = None if nrm is None else nrm[:, [0, 2, 1]]
    return v, nrm, mirrored


def _placed_normals(normals: np.ndarray, normal_matrix: np.ndarray) -> np.ndarray:
    """Per-corner normals (T, 3, 3) times the normal matrix, renormalised (float64: rounded to
    float32 once, when the soup is assembled). As one (3T, 3) × (3, 3) product, which NumPy hands
    to BLAS, and lengths by einsum: the stacked (T, 3, 3) product and ``linalg.norm`` took
    0.5-1.0 s for a 1 M-triangle mesh, this 0.14-0.29 s (the same values to 2.2e-16)."""
    flat = normals.reshape(-1, 3).astype(np.float64) @ normal_matrix.T
    length = np.sqrt(np.einsum("ij,ij->i", flat, flat))
    flat /= np.maximum(length, 1e-30)[:, None]
    return flat.reshape(normals.shape)


def _flat_normals(v: np.ndarray) -> np.ndarray:
    v = v.astype(np.float64)
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    return np.repeat(n[:, None, :], 3, axis=1)


def build_mesh_light(soup: TriangleSoup, materials: list):
    emissive = [i for i, m in enumerate(materials) if getattr(m, "emission", None) is not None]
    if not emissive or soup.count == 0:
        return None
    tri = np.nonzero(np.isin(soup.material, emissive))[0]
    if tri.size == 0:
        return None
    radiance = np.zeros((tri.size, 3))
    centroid_uv = soup.uvs[tri].mean(axis=1).astype(np.float64) if soup.uvs is not None else np.zeros((tri.size, 2))
    for mi in emissive:
        sel = soup.material[tri] == mi
        if sel.any():
            value = np.asarray(materials[mi].emission.bind(centroid_uv[sel]), dtype=np.float64)
            radiance[sel] = np.broadcast_to(value.reshape(-1, 3), (int(sel.sum()), 3))
    keep = radiance.max(axis=1) > 0
    tri, radiance = tri[keep], radiance[keep]
    if tri.size == 0:
        return None
    from ..lights.mesh import MeshLight
    textured = {}
    if any(not materials[mi].emission.is_constant for mi in emissive) and soup.uvs is not None:
        # Exact emission at sampled points: each triangle's UV corners and its material's
        # emission parameter (one slot per emissive material), evaluated per lane by the kernel.
        slot_of = np.full(len(materials), -1, np.int64)
        slot_of[emissive] = np.arange(len(emissive))
        textured = dict(uvs=soup.uvs[tri].astype(np.float64), emission=[materials[mi].emission for mi in emissive],
                        slots=slot_of[soup.material[tri]])
    # Two-sided per triangle unless its material emits from the front only (emission_sides).
    two_sided = ~np.array([bool(getattr(m, "emission_front_only", False)) for m in materials])[soup.material[tri]]
    light = MeshLight(soup.vertices[tri].astype(np.float64), radiance, two_sided=two_sided, **textured)
    light.triangle_ids = tri  # global triangle index of each emitter
    return light


def _corner_extremes(v: np.ndarray) -> np.ndarray:
    """(2, 3) float64: the per-axis minimum and maximum of corners (T, 3, 3). One strided 1-D
    reduction per axis: ``v.min(axis=(0, 1))`` took 0.11 s per extreme for 1 M triangles, this
    0.01 s for all six (the same values)."""
    flat = v.reshape(-1)
    return np.array([[flat[k::3].min() for k in range(3)], [flat[k::3].max() for k in range(3)]],
                    dtype=np.float64)


def scene_bounds(soup: TriangleSoup, lights: list, camera) -> tuple[np.ndarray, float]:
    # The soup's extremes in float32 (exact), not a float64 copy of every corner; moving
    # triangles at every motion step.
    pts = [_corner_extremes(v) for v in [soup.vertices] + list(getattr(soup, "motion", None) or [])
           if v.shape[0]]
    pts.append(camera.to_world[:3, 3][None, :])
    for light in lights:
        pos = getattr(light, "position", None)
        if pos is not None:
            pts.append(np.asarray(pos, dtype=np.float64).reshape(1, 3))
    allp = np.concatenate(pts)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    center = 0.5 * (lo + hi)
    radius = max(float(np.linalg.norm(hi - lo)) * 0.5, 1e-3)
    return center, radius
