"""Material presets in Blender (run inside bpy by tests/blender/test_blender_presets.py).

The add-on is loaded as an extension (``bl_ext.lamina_dev.lamina``) so that user presets go to
``bpy.utils.extension_path_user`` exactly as for users. Each case returns plain JSON; the
comparisons with the backend's parser happen in the pytest process.
"""
from __future__ import annotations

import importlib
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import bpy
import numpy as np

from . import build
from .ui_cases import Recorder

PACKAGE = os.environ.get("LAMINA_TEST_PACKAGE", "lamina")


def mod(name: str):
    return importlib.import_module(f"{PACKAGE}.addon.{name}")


def set_thumbnails(on: bool) -> None:
    """Background thumbnail renders after a save (on by default); the cases that do not test
    them turn them off so the menu and folder listings they check stay deterministic."""
    mod("preferences").get().user_preset_thumbnails = on


def export_dir(tmp, name) -> Path:
    d = Path(tmp) / "exports" / name
    d.mkdir(parents=True, exist_ok=True)
    return d


def stack_export(material, directory: Path | None, links: bool) -> dict:
    """A material's JSON as the scene exporter writes it (textures copied into ``directory``)."""
    images = mod("export.images").ImageExporter(directory, directory is not None, [])
    linked = mod("export.preset_link").linked_json(images) if links else None
    return mod("export.stack").stack_json(material, images, linked=linked)


# ------------------------------------------------------------------ images

def png(tmp, name: str, pixels: np.ndarray, colorspace: str):
    """An image file on disk (8-bit PNG), loaded as Blender loads a user's texture."""
    h, w, _ = pixels.shape
    img = bpy.data.images.new(name, w, h, alpha=True)
    rgba = np.concatenate([pixels, np.ones((h, w, 1))], axis=2).astype(np.float32)
    img.pixels.foreach_set(rgba.ravel())
    path = Path(tmp) / "images" / f"{name}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    img.filepath_raw = str(path)
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)
    loaded = bpy.data.images.load(str(path))
    loaded.colorspace_settings.name = colorspace
    return loaded


def pattern(w: int, h: int, seed: int, lo=0.1, hi=0.9) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return lo + (hi - lo) * rng.random((h, w, 3))


def generated(name: str, seed: int):
    """An image that exists only in memory (painted, unsaved): saved presets store it as PFM."""
    img = bpy.data.images.new(name, 8, 8, alpha=True, float_buffer=True)
    rgba = np.concatenate([pattern(8, 8, seed), np.ones((8, 8, 1))], axis=2).astype(np.float32)
    img.pixels.foreach_set(rgba.ravel())
    return img


# ------------------------------------------------------------------ stacks built in the editor

def rich_stacks(tmp) -> dict:
    """Materials using every field the stack editor has (textures of each kind, nesting)."""
    add_layer = mod("ops.stack").add_layer

    nested = bpy.data.materials.new("Nested Base")
    s = nested.lamina
    top = add_layer(s, "DIELECTRIC", 0)
    top.ior, top.roughness = 1.6, math.sqrt(0.05)
    top.thickness, top.sigma_t, top.albedo = 1.0, 0.5, (0.95, 0.9, 0.85)
    top.phase, top.vmf_kappa = "VMF", 20.0
    base = add_layer(s, "DIFFUSE", 1)
    base.color = (0.6, 0.5, 0.4)
    base.color_texture = png(tmp, "paint", pattern(16, 16, 1), "sRGB")
    s.use_stack = True

    a = bpy.data.materials.new("Rich A")
    s = a.lamina
    coat = add_layer(s, "DIELECTRIC", 0)
    coat.ior, coat.roughness, coat.use_anisotropy, coat.roughness_v = 1.45, 0.3, True, 0.5
    coat.distribution, coat.masking = "BECKMANN", "SEPARABLE"
    coat.roughness_texture = generated("rough", 2)
    coat.thickness, coat.thickness_texture = 0.7, png(tmp, "thick", pattern(16, 8, 3), "Non-Color")
    coat.use_chromatic, coat.sigma_t_rgb = True, (2.0, 1.0, 0.5)
    coat.albedo, coat.phase, coat.flake_stddev = (0.9, 0.8, 0.7), "MICROFLAKE", 0.2
    coat.flake_orientation = (0.5, 0.5, 0.0)
    coat.orientation_texture = png(tmp, "weave", pattern(8, 8, 4), "Non-Color")
    gap = add_layer(s, "NULL", 1)
    gap.sigma_t, gap.sigma_t_texture = 0.8, png(tmp, "density", pattern(8, 8, 5), "Non-Color")
    gap.albedo, gap.albedo_texture = (1.0, 1.0, 1.0), png(tmp, "tint", pattern(8, 8, 6), "sRGB")
    gap.phase, gap.hg_g = "HG", -0.3
    inner = add_layer(s, "DIELECTRIC", 2)
    inner.ior, inner.roughness = 1.2, 0.0
    inner.thickness, inner.sigma_t, inner.albedo = 1.3, 1.5, (0.7, 0.8, 0.9)
    inner.phase, inner.sggx_shape, inner.flake_orientation, inner.sggx_roughness = "SGGX", "FLAKE", (0, 0.2, 1), 0.4
    last = add_layer(s, "MATERIAL", 3)
    last.material = nested
    s.emission_strength, s.emission_color = 2.0, (1.0, 0.5, 0.25)
    s.use_stack = True

    c = bpy.data.materials.new("Rich C")
    s = c.lamina
    coat = add_layer(s, "DIELECTRIC", 0)
    coat.ior, coat.roughness = 1.5, math.sqrt(0.1)
    coat.thickness, coat.sigma_t, coat.albedo = 2.0, 0.25, (0.8, 0.8, 0.6)
    coat.phase, coat.sggx_shape, coat.flake_orientation, coat.sggx_roughness = "SGGX", "FIBER", (1, 0, 0), 0.3
    metal = add_layer(s, "CONDUCTOR", 1)
    metal.metal, metal.eta, metal.k = "CUSTOM", (0.2, 0.9, 1.1), (3.9, 2.4, 2.1)
    metal.tint, metal.roughness = (0.9, 0.8, 0.7), 0.35
    # The interfaces' own normal and bump maps (Blender's Normal Map and Bump nodes on a layer).
    coat.normal_texture, coat.normal_strength = png(tmp, "ripples", pattern(8, 8, 8, 0.4, 0.6), "Non-Color"), 0.6
    metal.bump_texture = png(tmp, "hammered", pattern(8, 8, 9), "Non-Color")
    metal.bump_distance, metal.bump_strength, metal.bump_invert = 0.02, 0.7, True
    s.use_stack = True

    d = bpy.data.materials.new("Plain Gold")
    s = d.lamina
    gold = add_layer(s, "CONDUCTOR", 0)
    gold.metal, gold.roughness = "Au", 0.25
    gold.bump_texture, gold.bump_distance = png(tmp, "brushed", pattern(8, 8, 10), "Non-Color"), 0.01
    s.use_stack = True
    return {"Rich A": a, "Rich C": c, "Plain Gold": d}


# ------------------------------------------------------------------ cases

def round_trip(tmp):
    """Save each material as a user preset, apply it to a new material, export both."""
    set_thumbnails(False)
    library = mod("presets.library")
    out = {}
    for name, src in rich_stacks(tmp).items():
        orig_dir, again_dir = export_dir(tmp, f"orig-{name}"), export_dir(tmp, f"again-{name}")
        original = stack_export(src, orig_dir, links=False)
        with bpy.context.temp_override(material=src):
            saved = bpy.ops.lamina.preset_save(name=name, description=f"test {name}", tags="test, round trip")
        slug = library.slugify(name)
        dst = bpy.data.materials.new(f"{name} again")
        with bpy.context.temp_override(material=dst):
            applied = bpy.ops.lamina.preset_apply(name=slug)
        path = library.find(slug)
        out[name] = {"status": [list(saved), list(applied)], "slug": slug, "file": str(path),
                     "original": original,
                     "reapplied": stack_export(dst, again_dir, links=False),
                     "orig_dir": str(orig_dir), "again_dir": str(again_dir),
                     "linked": stack_export(dst, None, links=True),
                     "state": mod("export.preset_link").state(dst),
                     "dropped": mod("export.preset_link").dropped(dst),
                     "src_state": mod("export.preset_link").state(src)}
    return out


def shipped(tmp):
    """Apply every shipped preset; export it linked (exact) and as the converted stack."""
    library = mod("presets.library")
    link = mod("export.preset_link")
    out = {}
    for entry in library.entries():
        if entry.user:
            continue
        mat = bpy.data.materials.new(entry.name)
        with bpy.context.temp_override(material=mat):
            status = bpy.ops.lamina.preset_apply(name=entry.name)
        copied = export_dir(tmp, f"copied-{entry.name}")          # File > Export with Copy Textures
        out[entry.name] = {"status": list(status), "file": str(entry.path), "state": link.state(mat),
                           "dropped": link.dropped(mat), "linked": stack_export(mat, None, links=True),
                           "stack": stack_export(mat, None, links=False),
                           "copied": stack_export(mat, copied, links=True), "copied_dir": str(copied)}
    return out


def _menu_entries(log) -> list[dict]:
    """(operator, text, icon, preset name) of every operator drawn into a recorded menu."""
    out = []
    for i, (name, args, kwargs) in enumerate(log):
        if name != "operator":
            continue
        entry = {"op": args[0], "text": kwargs.get("text"), "icon_value": kwargs.get("icon_value", 0),
                 "icon": kwargs.get("icon")}
        for later, values, _ in log[i + 1:i + 3]:
            if later == "set:name":
                entry["name"] = values[0]
        out.append(entry)
    return out


def menu(tmp):
    set_thumbnails(False)
    ops = mod("ops.presets")
    previews = mod("presets.previews")
    library = mod("presets.library")
    ui = mod("ui.material")
    # A user preset (saved without a thumbnail) must appear with the generic icon.
    mat = bpy.data.materials.new("Menu Test")
    gold = mod("ops.stack").add_layer(mat.lamina, "CONDUCTOR", 0)
    gold.metal = "Ag"
    mat.lamina.use_stack = True
    with bpy.context.temp_override(material=mat):
        bpy.ops.lamina.preset_save(name="Menu Test", overwrite=True)
    log = []
    ops.LAMINA_MT_material_presets.draw(SimpleNamespace(layout=Recorder(log)), bpy.context)
    entries = _menu_entries(log)
    # Thumbnails the menu loaded (headless Blender gives every icon id 0, so the menu's
    # icon_value cannot be checked here; the loaded pixels can).
    loaded = {}
    for key, preview in previews._collection.items():
        px = np.array(preview.image_pixels_float[:], dtype=np.float64).reshape(-1, 4)
        loaded[key.rsplit("|", 1)[0]] = {"size": list(preview.image_size), "mean_rgb": px[:, :3].mean(axis=0).tolist()}
    thumbnails = {e.name: str(e.thumbnail) if e.thumbnail else None for e in library.entries()}
    user_names = sorted(p.stem for p in library.user_dir().glob("*.json"))
    delete_log = []
    ops.LAMINA_MT_user_presets_delete.draw(SimpleNamespace(layout=Recorder(delete_log)), bpy.context)
    items = ops.browser_items(None, bpy.context)
    browser = [[i[0], i[3] if isinstance(i[3], str) else int(i[3])] for i in items]
    # The layer-stack panel: the presets menu, the link to the applied preset, the browser.
    with bpy.context.temp_override(material=mat):
        bpy.ops.lamina.preset_apply(name="gabardine")
    panel_log = []
    ui.draw_stack(Recorder(panel_log), mat)
    browser_log = []
    bpy.context.window_manager.lamina_preset_browser = "satin"
    ui.draw_preset_browser(Recorder(browser_log), bpy.context)
    known = {i.identifier for i in bpy.types.UILayout.bl_rna.functions["prop"].parameters["icon"].enum_items}
    used = {kw["icon"] for log_ in (log, delete_log, panel_log, browser_log) for _, _, kw in log_ if "icon" in kw}
    used |= {icon for _, _, _, icon, _ in items if isinstance(icon, str)}
    return {"unknown_icons": sorted(used - known), "entries": entries, "loaded": loaded, "thumbnails": thumbnails, "user_names": user_names, "delete": _menu_entries(delete_log), "browser": browser,
            "shipped_dir": str(library.SHIPPED), "user_dir": str(library.user_dir()),
            "panel": [[c[0], *[a for a in c[1] if isinstance(a, str)], c[2].get("text"), c[2].get("icon")]
                      for c in panel_log if c[0] in ("label", "menu", "operator")],
            "browser_panel": [[c[0], *[a for a in c[1] if isinstance(a, str)]] for c in browser_log]}


def user_folder(tmp):
    """Where user presets go, and that the backend child process finds them."""
    set_thumbnails(False)
    library = mod("presets.library")
    job = mod("engine.job")
    mat = bpy.data.materials.new("Folder Test")
    s = mat.lamina
    coat = mod("ops.stack").add_layer(s, "DIELECTRIC", 0)
    coat.ior, coat.roughness, coat.sigma_t, coat.albedo = 1.5, 0.2, 0.5, (0.9, 0.6, 0.3)
    coat.albedo_texture = png(tmp, "folder-tint", pattern(8, 8, 7), "sRGB")
    mod("ops.stack").add_layer(s, "DIFFUSE", 1).color = (0.5, 0.5, 0.5)
    s.use_stack = True
    with bpy.context.temp_override(material=mat):
        first = bpy.ops.lamina.preset_save(name="Folder Test")
        errors = []
        for kwargs in ({"name": "Folder Test"}, {"name": "car-paint-red"}):
            try:
                bpy.ops.lamina.preset_save(**kwargs)
            except RuntimeError as exc:       # an operator that reports an error raises here
                errors.append(str(exc).strip().splitlines()[-1])
        again = bpy.ops.lamina.preset_save(name="Folder Test", overwrite=True)
    folder = library.user_dir()
    expected = bpy.utils.extension_path_user(PACKAGE, path="presets")
    saved = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    env = mod("launch").user_environment()
    # The kernel cache would be the extension's own folder: share the test session's cache
    # instead (a second cold compile here would only cost time; test_extension covers it).
    env.pop("LAMINA_KERNEL_CACHE", None)
    # A scene that names the user preset renders in the backend child process...
    scene = Path(tmp) / "user-preset-scene.json"
    scene.write_text(json.dumps({
        "format": "lamina-scene", "version": 1, "film": {"width": 8, "height": 6},
        "camera": {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0, -1, -4], [0, 1, 0, 0], [0, 0, 0, 1]],
                   "frame": [[0.36, 0.27, -1], [0.36, -0.27, -1], [-0.36, -0.27, -1], [-0.36, 0.27, -1]]},
        "render": {"spp": 1},
        "materials": {"m": "folder-test"},
        "meshes": {"ball": {"shape": "sphere", "radius": 1.0, "segments": 16}},
        "objects": [{"mesh": "ball", "materials": ["m"]}],
        "world": {"type": "constant", "color": [0.5, 0.5, 0.5], "strength": 1}}))

    def render(child_env):
        cmd = [sys.executable, "-m", "backend", "render", str(scene), "-o", str(Path(tmp) / "user.exr"),
               "--workers", "1"]
        proc = subprocess.run(cmd, capture_output=True, text=True, env=child_env, cwd=tmp)
        return {"code": proc.returncode, "stderr": proc.stderr[-600:]}

    with_env = render(job.child_environment(env))          # what the render engine starts
    bare = job.child_environment()
    bare.pop("LAMINA_PRESET_PATH", None)
    without_env = render(bare)                              # control: the same without the folder
    listed_before = [e.name for e in library.entries() if e.user]
    deleted = list(bpy.ops.lamina.preset_delete(name="folder-test"))
    remaining = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    return {"status": [list(first), list(again)], "errors": errors, "folder": str(folder),
            "expected": expected, "extension_root": str(Path(job.EXTENSION_ROOT).resolve()),
            "user_resources": str(Path(bpy.utils.resource_path("USER")).resolve()),
            "saved": saved, "env": env, "with_env": with_env, "without_env": without_env,
            "listed_before": listed_before, "deleted": deleted, "remaining": remaining,
            "listed_after": [e.name for e in library.entries() if e.user]}


def user_thumbnail(tmp):
    """A saved preset gets a thumbnail rendered in the background; saving again replaces the
    pending render; deleting the preset removes the thumbnail."""
    set_thumbnails(True)
    jobs = mod("presets.thumbnail_jobs")
    library = mod("presets.library")
    mat = bpy.data.materials.new("Thumb Test")
    s = mat.lamina
    coat = mod("ops.stack").add_layer(s, "DIELECTRIC", 0)
    coat.ior, coat.roughness = 1.5, 0.1
    mod("ops.stack").add_layer(s, "DIFFUSE", 1).color = (0.6, 0.2, 0.1)
    s.use_stack = True
    t0 = time.monotonic()
    with bpy.context.temp_override(material=mat):
        first = bpy.ops.lamina.preset_save(name="Thumb Test")
        second = bpy.ops.lamina.preset_save(name="Thumb Test", overwrite=True)   # replaces the first render
    returned_after = time.monotonic() - t0
    # The operator does not wait for the render: when it returns, the render is still running.
    busy_after_save = jobs.busy()
    idle = jobs.wait(timeout=240)
    entry = next(e for e in library.entries() if e.name == "thumb-test")
    thumb = str(entry.thumbnail) if entry.thumbnail else None
    size = None
    if thumb:
        from backend.textures import read_image
        size = list(read_image(Path(thumb))[0].shape)
    deleted = list(bpy.ops.lamina.preset_delete(name="thumb-test"))
    return {"status": [list(first), list(second)], "returned_after": returned_after,
            "busy_after_save": busy_after_save, "idle": idle,
            "finished": jobs.finished(), "thumbnail": thumb, "size": size,
            "user_dir": str(library.user_dir()), "deleted": deleted,
            "thumbnail_after_delete": bool(thumb) and Path(thumb).exists()}


def repeated_saves(tmp, count: int = 40):
    """Saving over and over while thumbnail renders start and stop: each save cancels the running
    render and queues a new one. A background Python thread once crashed Blender here (SIGSEGV
    inside that thread while the main thread ran ``bpy.ops``); the run must survive every save
    and end with exactly one completed render."""
    set_thumbnails(True)
    jobs = mod("presets.thumbnail_jobs")
    mat = bpy.data.materials.new("Churn")
    s = mat.lamina
    mod("ops.stack").add_layer(s, "DIELECTRIC", 0).roughness = 0.2
    mod("ops.stack").add_layer(s, "DIFFUSE", 1).color = (0.2, 0.4, 0.6)
    s.use_stack = True
    before = len(jobs.finished())
    status = set()
    with bpy.context.temp_override(material=mat):
        for i in range(count):
            status.update(bpy.ops.lamina.preset_save(name="Churn", overwrite=True))
            time.sleep(0.005 * (i % 7))          # vary where in the child's start-up the next save lands
    idle = jobs.wait(timeout=240)
    ended = [f for f in jobs.finished()[before:] if f["path"].endswith("churn.json")]
    deleted = list(bpy.ops.lamina.preset_delete(name="churn"))
    return {"status": sorted(status), "idle": idle, "ended": ended, "deleted": deleted}


PARTIAL = {
    "type": "layered", "estimator": "uni", "_comment": "comments are not fields",
    "interfaces": [
        {"type": "dielectric", "ior": 1.5, "roughness": 0.1, "normal": [0.0, 0.2, 1.0],
         "transmission_color": [0.9, 0.9, 0.9]},
        {"type": "conductor", "metal": "Au", "roughness": 0.2, "tint": [1.2, 1.0, 1.0]}],
    "media": [{"thickness": 1.0, "sigma_t": 1.0, "albedo": [0.5, 0.5, 0.5],
               "phase": {"type": "sggx", "matrix": [1.0, 1.0, 0.5, 0.0, 0.0, 0.0]}}]}


def dropped_fields(tmp):
    """A preset with fields the editor cannot show: reported, exported exactly until edited."""
    link = mod("export.preset_link")
    path = Path(tmp) / "partial.json"
    path.write_text(json.dumps({"format": "lamina-preset", "version": 1, "name": "partial",
                                "category": "test", "description": "d", "tags": [], "material": PARTIAL}))
    build.scene()
    build.camera()
    mat = bpy.data.materials.new("Partial")
    build.plane(material=mat)
    with bpy.context.temp_override(material=mat):
        bpy.ops.lamina.preset_apply(filepath=str(path))
    exact = {"state": link.state(mat), "dropped": link.dropped(mat), "linked": stack_export(mat, None, True)}
    export_scene = mod("export").export_scene
    first = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / "scene-exact")
    mat.lamina.layers[0].roughness = 0.5                  # an edit detaches the preset
    mat.update_tag()                                      # (the UI tags edits; Python does not)
    edited = {"state": link.state(mat), "stack": stack_export(mat, None, True)}
    second = export_scene(bpy.context.evaluated_depsgraph_get(), Path(tmp) / "scene-edited")
    doc = json.loads(second.path.read_text())
    with bpy.context.temp_override(material=mat):
        bpy.ops.lamina.preset_apply(filepath=str(path))
    return {"exact": exact, "exact_notes": first.notes, "exported_exact": json.loads(first.path.read_text())["materials"],
            "edited": edited, "edited_notes": second.notes, "exported_edited": doc["materials"],
            "reapplied": link.state(mat)}
