"""Rendered-shading cases (run inside Blender by tests/blender/test_viewport.py).

Headless Blender has no viewport and cannot draw, so each case plays Blender's part: a stand-in
engine (the methods ``view_update``/``view_draw`` use), a region/region-data context built from
the scene camera's own matrices, the add-on's timer called by hand, and a recording drawer in
place of the GPU one (``viewport.make_drawer``). The session behind it is the real renderer.
"""
from __future__ import annotations

import gc
import math
import os
import signal
import time
from types import SimpleNamespace

import bpy
import numpy as np

from . import build

W, H = 32, 24


class StubEngine:
    """What view_update/view_draw need of the RenderEngine Blender would create."""

    is_preview = False

    def __init__(self):
        self.viewport = None
        self.stats: list[str] = []
        self.redraws = 0
        self.bound = 0

    def update_stats(self, a, b):
        if not self.stats or self.stats[-1] != b:
            self.stats.append(b)

    def tag_redraw(self):
        self.redraws += 1

    def bind_display_space_shader(self, scene):
        self.bound += 1

    def unbind_display_space_shader(self):
        self.bound -= 1

    def get_preview_pixel_size(self, scene):
        return 1


class RecordingDrawer:
    """Stands in for the GPU drawer: remembers every upload and every draw."""

    log: list = []

    def __init__(self):
        self.frame = None

    def upload(self, frame):
        self.frame = frame
        RecordingDrawer.log.append(("upload", frame.generation, frame.frame, frame.scale, frame.spp,
                                    frame.width, frame.height, float(np.mean(frame.pixels[..., :3]))))

    def draw(self, engine, scene, width, height):
        assert engine.bound == 0, "display space shader bound twice"
        f = self.frame
        RecordingDrawer.log.append(("draw", f.generation, f.frame, f.scale, f.spp, width, height))

    def free(self):
        RecordingDrawer.log.append(("free",))


def _engine_class():
    import sys
    package = os.environ.get("LAMINA_TEST_PACKAGE", "lamina")
    return sys.modules[f"{package}.addon.engine.engine"].LaminaRenderEngine


def _viewport_module():
    import sys
    package = os.environ.get("LAMINA_TEST_PACKAGE", "lamina")
    return sys.modules[f"{package}.addon.engine.viewport"]


def _context(scene, camera_view=False, width=W, height=H, ortho=False, border=None):
    dg = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera
    view = cam.matrix_world.normalized().inverted()
    if ortho:
        cam.data.type = "ORTHO"
    window = cam.calc_matrix_camera(dg, x=width, y=height)
    region = SimpleNamespace(width=width, height=height)
    rv3d = SimpleNamespace(view_matrix=view, window_matrix=window, is_perspective=not ortho,
                           view_perspective="CAMERA" if camera_view else ("ORTHO" if ortho else "PERSP"))
    space = SimpleNamespace(use_render_border=border is not None)
    if border is not None:
        (space.render_border_min_x, space.render_border_min_y,
         space.render_border_max_x, space.render_border_max_y) = border
    return SimpleNamespace(region=region, region_data=rv3d, space_data=space, scene=scene)


def _scene(samples=4):
    sc = build.scene()
    build.camera()
    build.plane(material=build.diffuse_material("Grey", (0.5, 0.5, 0.5)), size=6)
    build.uv_sphere(material=build.diffuse_material("Ball", (0.7, 0.3, 0.2)))
    build.light("Lamp", "POINT", (1.0, -1.0, 3.0), energy=300.0)
    build.world_colour((0.2, 0.2, 0.2))
    sc.lamina.viewport_samples = samples
    sc.lamina.workers = 1
    return sc


class Driver:
    """Blender's part: view_update, then the timer and view_draw whenever it asks for a redraw."""

    def __init__(self, scene, **context):
        self.engine = StubEngine()
        self.cls = _engine_class()
        self.vp = _viewport_module()
        self.vp.make_drawer = RecordingDrawer
        RecordingDrawer.log = []
        self.scene = scene
        self.context = _context(scene, **context)
        self.t0 = time.perf_counter()

    def update(self):
        """Blender calls view_update after each depsgraph evaluation, with the updates listed
        in ``depsgraph.updates``; a depsgraph_update_post handler sees the same depsgraph."""
        seen = []

        def handler(scene, depsgraph):
            seen.append(1)
            self.cls.view_update(self.engine, self.context, depsgraph)

        bpy.app.handlers.depsgraph_update_post.append(handler)
        try:
            bpy.context.view_layer.update()
        finally:
            bpy.app.handlers.depsgraph_update_post.remove(handler)
        if not seen:                       # nothing to evaluate (first call): no updates
            self.cls.view_update(self.engine, self.context, bpy.context.evaluated_depsgraph_get())

    def draw(self):
        self.cls.view_draw(self.engine, self.context, bpy.context.evaluated_depsgraph_get())

    def run(self, until, timeout=300.0):
        """Tick and draw until ``until(self)``; returns seconds waited. The timeout allows a cold
        kernel cache (the first session of a run may compile the kernels: ~80 s CPU)."""
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < timeout:
            before = self.engine.redraws
            self.vp._tick()
            if self.engine.redraws != before:
                self.draw()
            if until(self):
                return time.perf_counter() - t0
            time.sleep(0.01)
        raise AssertionError(f"timed out; log tail {RecordingDrawer.log[-5:]}, stats {self.engine.stats[-3:]}")

    @property
    def client(self):
        return self.engine.viewport.client

    def draws(self):
        return [e for e in RecordingDrawer.log if e[0] == "draw"]

    def drawn_generation(self, g):
        return any(e[1] == g for e in self.draws())


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:                                   # a zombie counts as gone
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _wait_gone(pid, timeout=5.0):
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < timeout:
        if not _alive(pid):
            return True
        time.sleep(0.02)
    return False


# ---------------------------------------------------------------------- cases

def progressive(tmp):
    """Enter Rendered mode: frames arrive, reduced first, then full resolution up to the
    Viewport Samples, then the session idles (its CPU time stops growing)."""
    sc = _scene(samples=4)
    d = Driver(sc)
    d.update()
    first = d.run(lambda d: d.draws())
    d.run(lambda d: d.client.idle and d.draws()[-1][4] == 4)
    pid = d.client.pid
    cpu = _cpu(pid)
    time.sleep(1.0)
    for _ in range(10):
        d.vp._tick()
    idle_cpu = _cpu(pid) - cpu
    out = {"first": first, "log": RecordingDrawer.log, "stats": d.engine.stats, "idle_cpu": idle_cpu,
           "generation": d.client.generation, "bound": d.engine.bound}
    d.engine.viewport.free()
    out["gone"] = _wait_gone(pid)
    return out


def _cpu(pid):
    with open(f"/proc/{pid}/stat") as f:
        parts = f.read().rsplit(")", 1)[1].split()
    return (int(parts[11]) + int(parts[12])) / os.sysconf("SC_CLK_TCK")


def edits(tmp):
    """Each kind of edit reaches the session as its own section(s), rebuilds only what it needs
    and restarts accumulation; after an edit, no frame of an older generation is drawn."""
    sc = _scene(samples=2)
    coat = bpy.data.materials.new("Coat")
    from lamina.addon.ops.stack import add_layer
    top = add_layer(coat.lamina, "DIELECTRIC", 0)
    top.ior, top.roughness = 1.5, 0.2
    add_layer(coat.lamina, "DIFFUSE", 1).color = (0.6, 0.2, 0.1)
    coat.lamina.use_stack = True
    build.plane("Card", size=1.0, material=coat, z=0.05).location = (1.5, 0.0, 0.0)
    d = Driver(sc)
    d.update()
    d.run(lambda d: d.client.idle)
    sent_log = []
    client = d.client
    original_send = client.send_update

    def send_update(changes):
        sent_log.append(sorted(changes))
        g = original_send(changes)
        RecordingDrawer.log.append(("send", g))
        return g

    client.send_update = send_update
    steps = []

    def step(name, change, view=False):
        g0 = client.generation
        n_log = len(RecordingDrawer.log)
        n_sent = len(sent_log)
        change()
        if view:
            bpy.context.view_layer.update()
            d.draw()
        else:
            d.update()
        t0 = time.perf_counter()
        d.run(lambda d: client.generation > g0 and d.drawn_generation(client.generation))
        first = time.perf_counter() - t0
        d.run(lambda d: client.idle and d.draws()[-1][4] == 2)
        g = client.generation
        later = RecordingDrawer.log[n_log:]
        sends = [i for i, e in enumerate(later) if e[0] == "send"]
        after_send = later[sends[0]:] if sends else []
        steps.append({"name": name, "generation": g, "sent": sent_log[n_sent:],
                      "rebuilt": client.last_updated["rebuilt"] if client.last_updated else None,
                      "stale_draws": [e for e in after_send if e[0] == "draw" and e[1] < g],
                      "draws_before_send": len([e for e in later[:sends[0] if sends else 0] if e[0] == "draw"]),
                      "generations_drawn": sorted({e[1] for e in later if e[0] == "draw"}),
                      "spp": [e[4] for e in later if e[0] == "draw" and e[1] == g and e[3] == 1],
                      "first": first})

    ball = bpy.data.objects["Sphere"]
    step("transform", lambda: setattr(ball, "location", (0.3, 0.0, 1.0)))
    step("material", lambda: setattr(
        bpy.data.materials["Ball"].node_tree.nodes["Diffuse BSDF"].inputs["Color"], "default_value",
        (0.1, 0.8, 0.1, 1.0)))
    def stack_edit():
        coat.lamina.layers[0].ior = 1.3
        # The properties editor tags the owner ID after a change (RNA_property_update); a
        # Python assignment to an add-on property does not, so the case does what the UI does.
        coat.update_tag()
    step("stack", stack_edit)
    step("light", lambda: setattr(bpy.data.lights["Lamp"], "energy", 600.0))
    step("world", lambda: build.world_colour((0.5, 0.1, 0.1)))
    step("add", lambda: build.uv_sphere("Extra", material=bpy.data.materials["Grey"],
                                        location=(-1.5, 0, 0.5), radius=0.4))
    step("remove", lambda: bpy.data.objects.remove(bpy.data.objects["Extra"]))

    def move_view():
        cam = sc.camera
        cam.location.x += 0.5
        bpy.context.view_layer.update()
        d.context.region_data.view_matrix = cam.matrix_world.normalized().inverted()
    step("view", move_view, view=True)

    def resize():
        d.context.region.width, d.context.region.height = 40, 20
        dg = bpy.context.evaluated_depsgraph_get()
        d.context.region_data.window_matrix = sc.camera.calc_matrix_camera(dg, x=40, y=20)
    step("resize", resize, view=True)
    step("settings", lambda: setattr(sc.lamina, "max_bounces", 3))
    out = {"steps": steps, "stats": d.engine.stats[-1], "stale_frames": client.stale_frames}
    pid = client.pid
    d.engine.viewport.free()
    out["gone"] = _wait_gone(pid)
    return out


def _start(samples=2, **context):
    sc = _scene(samples=samples)
    d = Driver(sc, **context)
    d.update()
    d.run(lambda d: d.client.idle)
    return sc, d


def lifecycle(tmp):
    """Every way a viewport render ends stops its session: the engine freed by Blender (seen by
    the timer through a weak reference), the engine's __del__, opening a file (load_pre) and
    disabling the add-on. Nothing survives: the process group is gone."""
    import addon_utils
    out = {}
    # 1. Blender frees the engine (leaving Rendered mode): the timer notices.
    sc, d = _start()
    pid = d.client.pid
    d.engine = None
    gc.collect()
    d.vp._tick()
    out["engine_dropped"] = _wait_gone(pid)
    # 2. The engine's __del__ (what Blender calls when it frees the engine).
    sc, d = _start()
    pid = d.client.pid
    d.cls.__del__(d.engine)
    out["engine_del"] = _wait_gone(pid)
    out["del_twice"] = (d.cls.__del__(d.engine), True)[1]
    # 3. File > Open / New (load_pre).
    sc, d = _start()
    pid = d.client.pid
    d.vp._load_pre(None)
    out["load_pre"] = _wait_gone(pid)
    out["sessions_after_load"] = len(d.vp._SESSIONS)
    # 4. Disabling the add-on.
    sc, d = _start()
    pid = d.client.pid
    vp = d.vp
    addon_utils.disable("lamina", default_set=True)
    out["unregister"] = _wait_gone(pid)
    out["timer_after_unregister"] = bpy.app.timers.is_registered(vp._tick)
    addon_utils.enable("lamina", default_set=True)
    # 5. Interpreter exit (atexit): kill_all.
    sc, d = _start()
    pid = d.client.pid
    d.vp.kill_all()
    out["atexit"] = _wait_gone(pid)
    d.vp.stop_all()
    return out


def crash(tmp):
    """The session process dies: the viewport says so in its header (one line), the console
    gets the same line once, and nothing raises."""
    import contextlib
    import io
    sc, d = _start()
    pid = d.client.pid
    os.kill(pid, signal.SIGKILL)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        d.run(lambda d: d.client.error is not None, timeout=10)
        for _ in range(5):
            d.vp._tick()
        d.draw()
        d.update()
    out = {"status": d.engine.stats[-1], "console": err.getvalue(), "error": d.client.error}
    d.engine.viewport.free()
    return out


def export_error(tmp):
    """A scene that cannot be exported (an empty layer stack): one line in the header and the
    console, no traceback; fixing it brings the image back."""
    import contextlib
    import io
    sc, d = _start()
    mat = bpy.data.materials["Ball"]
    mat.lamina.use_stack = True              # a stack without interfaces
    mat.update_tag()
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        d.update()
        d.draw()
    status = d.engine.stats[-1]
    g0 = d.client.generation
    mat.lamina.use_stack = False                 # back to what the session renders already
    mat.update_tag()
    d.update()
    d.draw()
    out = {"status": status, "console": err.getvalue(), "after": d.engine.stats[-1],
           "new_generation": d.client.generation != g0}
    d.engine.viewport.free()
    # The error already there when entering Rendered mode: nothing is sent until it is fixed,
    # then the whole scene goes out and renders.
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = _scene(samples=2)
    mat = bpy.data.materials["Ball"]
    mat.lamina.use_stack = True
    d = Driver(sc)
    with contextlib.redirect_stderr(io.StringIO()):
        d.update()
        d.draw()
        d.draw()
    out["entering_status"] = d.engine.stats[-1]
    out["entering_scene_sent"] = d.engine.viewport.scene_sent
    uploads = len([e for e in RecordingDrawer.log if e[0] == "upload"])
    mat.lamina.use_stack = False
    mat.update_tag()
    d.update()
    d.run(lambda d: d.client.idle and d.drawn_generation(d.client.generation))
    out["fixed_status"] = d.engine.stats[-1]
    out["fixed_frames"] = len([e for e in RecordingDrawer.log if e[0] == "upload"]) - uploads
    d.engine.viewport.free()
    return out


def coalesce(tmp):
    """Edits made while the session has not shown the previous one wait and go out together."""
    sc, d = _start(samples=64)
    sent = []
    original = d.client.send_update

    def send_update(changes):
        sent.append(sorted(changes))
        return original(changes)

    d.client.send_update = send_update
    time.sleep(0.2)                                     # the last image has been on screen long enough
    bpy.data.lights["Lamp"].energy = 500.0
    d.update()                                          # sent at once
    bpy.data.objects["Sphere"].location.x = 0.4
    d.update()                                          # waits: generation 2 has no image yet
    bpy.data.lights["Lamp"].energy = 700.0
    d.update()                                          # waits too, merged with the move
    waiting = sorted(d.engine.viewport.pending)
    sent_before = list(sent)
    g = d.client.generation + 1
    d.run(lambda d: d.client.generation >= g and d.drawn_generation(g))
    out = {"sent_before": sent_before, "waiting": waiting, "sent": sent,
           "lights": d.engine.viewport.live.sent["lights"][0]["power"]}
    d.engine.viewport.free()
    return out


def samples_change(tmp):
    """Raising Viewport Samples continues the accumulation (no new generation)."""
    sc, d = _start(samples=2)
    g = d.client.generation
    sc.lamina.viewport_samples = 5
    sc.update_tag()
    d.update()
    d.run(lambda d: d.client.idle and d.draws()[-1][4] == 5)
    out = {"generation_before": g, "generation_after": d.client.generation,
           "spp": [e[4] for e in d.draws() if e[1] == g]}
    # The final render's samples, noise threshold, minimum samples and time limit do not apply
    # to the viewport: editing them sends nothing and keeps the image.
    sc.lamina.samples = 7
    sc.lamina.noise_threshold = 0.05
    sc.lamina.min_samples = 3
    sc.lamina.time_limit = 9.0
    sc.update_tag()
    d.update()
    d.run(lambda d: not d.engine.viewport.pending)
    out["generation_after_final_settings"] = d.client.generation
    d.engine.viewport.free()
    return out


def views(tmp):
    """The viewport camera from the region matrices next to the scene camera's export, for
    perspective (with shift and each sensor fit) and orthographic cameras."""
    from lamina.addon.export.camera import camera_json
    from lamina.addon.export.view import view_camera
    sc = _scene()
    cam = sc.camera
    out = []
    for kind, fit, shift, size in (("PERSP", "AUTO", (0.0, 0.0), (32, 24)), ("PERSP", "AUTO", (0.2, -0.1), (32, 24)),
                                   ("PERSP", "VERTICAL", (0.1, 0.0), (24, 32)),
                                   ("PERSP", "HORIZONTAL", (0.0, 0.15), (40, 20)),
                                   ("ORTHO", "AUTO", (0.1, 0.1), (32, 24))):
        cam.data.type, cam.data.sensor_fit = kind, fit
        cam.data.shift_x, cam.data.shift_y = shift
        sc.render.resolution_x, sc.render.resolution_y = size
        bpy.context.view_layer.update()
        dg = bpy.context.evaluated_depsgraph_get()
        view = cam.matrix_world.normalized().inverted()
        window = cam.calc_matrix_camera(dg, x=size[0], y=size[1])
        out.append({"kind": kind, "fit": fit, "shift": shift,
                    "exported": camera_json(cam, sc),
                    "viewport": view_camera(view, window, kind == "PERSP")})
    return out


def borders(tmp):
    """Camera view with a render border (crop inside the camera frame), a View Region border,
    and a 2-pixel viewport resolution: the session renders only the crop (alpha 0 elsewhere)."""
    out = {}
    for name, context in (("camera", {"camera_view": True}),
                          ("region", {"border": (0.5, 0.5, 1.0, 1.0)})):
        sc = _scene(samples=1)
        if name == "camera":
            sc.render.use_border = True
            sc.render.border_min_x, sc.render.border_max_x = 0.25, 0.75
            sc.render.border_min_y, sc.render.border_max_y = 0.0, 0.5
        d = Driver(sc, **context)
        d.update()
        d.run(lambda d: d.client.idle)
        film = d.engine.viewport.live.sent["film"]
        alpha = RecordingDrawer.log and d.engine.viewport.drawer.frame.pixels[..., 3]
        out[name] = {"crop": film.get("crop"), "size": [film["width"], film["height"]],
                     "alpha_rows": [int(v) for v in (alpha > 0).sum(axis=1)],
                     "alpha_cols": [int(v) for v in (alpha > 0).sum(axis=0)]}
        d.engine.viewport.free()
    sc = _scene(samples=1)
    d = Driver(sc)
    d.engine.get_preview_pixel_size = lambda scene: 2
    d.update()
    d.run(lambda d: d.client.idle)
    f = d.engine.viewport.drawer.frame
    out["pixel_size_2"] = [f.width, f.height, d.draws()[-1][5], d.draws()[-1][6]]
    d.engine.viewport.free()
    return out


# ---------------------------------------------------------------------- measurement (not a test)

def _demo_scene(width, height, samples):
    """demo/demo.json rebuilt in Blender: three 128-segment spheres with the reference stack, the
    coated copper stack and glass (through the preset converter), a checker floor, an area light,
    a sun and a constant world; the camera of the file (50 mm lens on a 36 mm sensor)."""
    import json
    from pathlib import Path
    from mathutils import Matrix
    from lamina.addon.presets.convert import material_from_json
    from lamina.backend.geometry.mesh import uv_sphere
    root = Path(__file__).resolve().parents[3]
    doc = json.loads((root / "demo" / "demo.json").read_text())
    sc = build.scene()
    sc.render.resolution_x, sc.render.resolution_y = width, height
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens, cam_data.sensor_width, cam_data.sensor_fit = 50.0, 36.0, "HORIZONTAL"
    cam = build.link(bpy.data.objects.new("Camera", cam_data))
    cam.matrix_world = Matrix(doc["camera"]["to_world"])
    sc.camera = cam
    mats = {}
    for name in ("reference", "coated_copper", "glass"):
        mats[name] = bpy.data.materials.new(name)
        material_from_json(mats[name], doc["materials"][name], root / "demo", name)
    floor_mat = build.diffuse_material("floor")
    tree = floor_mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(str(root / "demo" / "textures" / "checker.png"))
    tree.links.new(tex.outputs["Color"], tree.nodes["Diffuse BSDF"].inputs["Color"])
    mats["floor"] = floor_mat
    sphere = uv_sphere(0.75, 128)
    me = bpy.data.meshes.new("ball")
    me.from_pydata(sphere.positions.tolist(), [], sphere.indices.tolist())
    me.shade_smooth()
    me.materials.append(None)
    for obj in doc["objects"]:
        if obj["mesh"] == "ball":              # one mesh, three objects: the slot links to each object
            o = build.link(bpy.data.objects.new(obj["name"], me))
            o.matrix_world = Matrix(obj["to_world"])
            o.material_slots[0].link = "OBJECT"
            o.material_slots[0].material = mats[obj["materials"][0]]
    build.plane("floor", size=40.0, material=floor_mat)
    for l in doc["lights"]:
        if l["type"] == "area":
            ob = build.light("Area", "AREA", energy=l["power"], shape="RECTANGLE", size=l["size"],
                             size_y=l["size_y"], color=l["color"])
        else:
            ob = build.light("Sun", "SUN", energy=l["strength"], angle=math.radians(l["angle"]), color=l["color"])
        ob.matrix_world = Matrix(l["to_world"])
    world = build.world_colour(tuple(doc["world"]["color"]), doc["world"]["strength"])
    sc.lamina.max_bounces = doc["render"]["max_bounces"]
    sc.lamina.viewport_samples = samples
    sc.lamina.workers = 0
    bpy.context.view_layer.update()
    return sc, world


def demo_latency(tmp, width=960, height=540, samples=4, repeats=3, standby=True):
    """Rendered mode on the demo scene: first image after entering it (pre-started session, warm
    kernel cache), first image after a view move and after a stack edit, session CPU when idle."""
    sc, _ = _demo_scene(width, height, samples)
    vp = _viewport_module()
    runs = []
    for r in range(repeats):
        if standby:
            vp._STANDBY["client"] = vp.start_client(int(sc.lamina.workers))
            t = time.perf_counter()
            while not vp._STANDBY["client"].warm:
                vp._STANDBY["client"].poll()
                time.sleep(0.02)
                assert time.perf_counter() - t < 120, vp._STANDBY["client"].job.stderr_text()
        d = Driver(sc, width=width, height=height)
        cpu = lambda: _cpu(d.client.pid) if d.engine.viewport and d.client else 0.0  # noqa: E731
        t0 = time.perf_counter()
        d.update()
        export_s = time.perf_counter() - t0
        d.run(lambda d: d.draws())
        first = time.perf_counter() - t0
        first_frame = d.draws()[0]
        d.run(lambda d: any(e[3] == 1 for e in d.draws()))          # a full-resolution image
        time.sleep(0.2)
        # view move: orbit the view a little (what the region's matrices do when navigating)
        rv3d = d.context.region_data
        from mathutils import Matrix
        rv3d.view_matrix = rv3d.view_matrix @ Matrix.Rotation(math.radians(2.0), 4, "Z")
        g0 = d.client.generation
        c0 = cpu()
        t0 = time.perf_counter()
        d.draw()
        d.run(lambda d: d.client.generation > g0 and d.drawn_generation(d.client.generation))
        move = time.perf_counter() - t0
        move_cpu = cpu() - c0
        time.sleep(0.2)
        # stack edit: the top interface's IOR of the reference stack
        mat = bpy.data.materials["reference"]
        mat.lamina.layers[0].ior = 1.45 + 0.01 * r
        mat.update_tag()
        g0 = d.client.generation
        c0 = cpu()
        t0 = time.perf_counter()
        d.update()
        d.run(lambda d: d.client.generation > g0 and d.drawn_generation(d.client.generation))
        edit = time.perf_counter() - t0
        edit_cpu = cpu() - c0
        updated = d.client.last_updated
        d.run(lambda d: d.client.idle, timeout=600)
        time.sleep(0.5)
        c0 = cpu()
        time.sleep(5.0)
        idle_cpu = (cpu() - c0) / 5.0
        runs.append({"first": first, "export_and_send": export_s, "first_scale": first_frame[3],
                     "move": move, "move_cpu": move_cpu, "edit": edit, "edit_cpu": edit_cpu,
                     "edit_rebuilt": updated["rebuilt"], "edit_timings": updated["timings"],
                     "idle_cpu_fraction": idle_cpu, "load": os.getloadavg()})
        d.engine.viewport.free()
        mat.lamina.layers[0].ior = 1.5
    return runs


def _roughness(pixels):
    """Mean absolute difference between horizontal neighbours (luminance): noise shows here."""
    lum = pixels[..., :3].mean(axis=2)
    return float(np.abs(np.diff(lum, axis=1)).mean())


def denoise(tmp):
    """Render › Denoise Viewport: the final frame (Viewport Samples reached) is drawn denoised,
    the frames before it as rendered; switched off, the same final frame is drawn as rendered."""
    sc = _scene(samples=4)
    sc.lamina.use_viewport_denoising = True
    d = Driver(sc, width=96, height=72)
    d.update()
    uploads = []
    original = RecordingDrawer.upload

    def upload(self, frame):
        uploads.append(frame)
        original(self, frame)

    RecordingDrawer.upload = upload
    try:
        d.run(lambda d: d.client.idle and uploads and uploads[-1].final and d.engine.viewport.denoised)
        noisy_first = uploads[-2]
        status_on = d.engine.stats[-1] if d.engine.stats else None
        shown = uploads[-1]
        earlier = [bool(f.final) for f in uploads[:-2]]
        sc.lamina.use_viewport_denoising = False
        d.update()
        d.draw()
        after_off = uploads[-1]
        status_off = d.engine.stats[-1] if d.engine.stats else None
        # The converged image: more Viewport Samples continue the same accumulation.
        sc.lamina.viewport_samples = 1024
        d.update()
        d.run(lambda d: d.client.idle and uploads[-1].final and uploads[-1].spp == 1024)
        converged = uploads[-1].pixels[..., :3]
    finally:
        RecordingDrawer.upload = original
    from lamina.addon.engine.session_client import read_frame_file  # noqa: F401 (import check)
    out = {"status_on": status_on, "status_off": status_off,
           "denoised_roughness": _roughness(shown.pixels), "noisy_roughness": _roughness(after_off.pixels),
           "denoised_rmse": float(np.sqrt(np.mean((shown.pixels[..., :3] - converged) ** 2))),
           "noisy_rmse": float(np.sqrt(np.mean((after_off.pixels[..., :3] - converged) ** 2))),
           "same_frame": shown.frame == after_off.frame == noisy_first.frame,
           "noisy_first_equal": bool(np.array_equal(noisy_first.pixels, after_off.pixels)),
           "features": shown.features is not None,
           "denoised_mean": float(shown.pixels[..., :3].mean()), "noisy_mean": float(after_off.pixels[..., :3].mean()),
           "finite": bool(np.isfinite(shown.pixels).all()),
           "albedo_mean": [float(v) for v in shown.features[..., :3].reshape(-1, 3).mean(axis=0)],
           "normal_z_mean": float(shown.features[..., 5].mean()),
           "earlier_final": earlier}
    d.engine.viewport.free()
    return out
