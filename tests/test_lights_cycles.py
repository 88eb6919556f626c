"""Brightness parity with Cycles itself (bpy 5.0.1): a Lambertian plane lit by each Blender light
type is rendered by Cycles and compared, pixel by pixel, with the irradiance of the matching
Lamina light estimated from ``sample()``. Also the environment texture's orientation, including a
Mapping node, from camera rays that look at the world.

Cycles jitters camera rays over its pixel filter (``cycles.filter_width``), so the filter is made
tiny and Lamina is evaluated at the pixel centres. Tolerance: 4 standard errors of the per-pixel
ratio Cycles/Lamina of the summed pixels (both are Monte Carlo estimates), plus float32 rounding for delta lights.
"""
import math

import numpy as np
import pytest

from backend.lights.area import AreaLight, CollimatedAreaLight
from backend.lights.environment import EnvironmentMap
from backend.lights.point import PointLight
from backend.lights.profiles import CyclesSpread
from backend.lights.spot import SpotLight
from backend.lights.sun import SunLight

pytestmark = pytest.mark.blender

RES = 16
ALBEDO = 0.5


@pytest.fixture(scope="module")
def cycles(tmp_path_factory):
    bpy = pytest.importorskip("bpy")
    return bpy, tmp_path_factory.mktemp("cycles")


def reset(bpy):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.max_bounces = 0
    sc.cycles.filter_width = 0.01
    sc.render.resolution_x = sc.render.resolution_y = RES
    sc.render.resolution_percentage = 100
    sc.render.threads_mode = "FIXED"
    sc.render.threads = 1
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.world = bpy.data.worlds.new("w")
    sc.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    return sc


def add_plane_and_camera(bpy, sc):
    me = bpy.data.meshes.new("plane")
    me.from_pydata([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [], [(0, 1, 2, 3)])
    mat = bpy.data.materials.new("grey")
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (ALBEDO, ALBEDO, ALBEDO, 1)
    diffuse.inputs["Roughness"].default_value = 0.0
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(diffuse.outputs[0], out.inputs[0])
    me.materials.append(mat)
    sc.collection.objects.link(bpy.data.objects.new("plane", me))
    cam = bpy.data.cameras.new("cam")
    cam.type = "ORTHO"
    cam.ortho_scale = 4.0
    co = bpy.data.objects.new("cam", cam)
    co.location = (0, 0, 5)
    sc.collection.objects.link(co)
    sc.camera = co


def render(bpy, sc, path, spp):
    import OpenImageIO as oiio
    sc.cycles.samples = spp
    sc.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    inp = oiio.ImageInput.open(str(path))
    px = inp.read_image(0, 0, 0, 3, oiio.FLOAT)
    inp.close()
    return np.asarray(px, dtype=np.float64).reshape(RES, RES, 3)


def pixel_centres():
    c = -2 + (np.arange(RES) + 0.5) * (4.0 / RES)
    X, Y = np.meshgrid(c, c[::-1])           # row 0 = top = +Y
    return np.column_stack([X.ravel(), Y.ravel(), np.zeros(RES * RES)])


def lamina_radiance(light, n, rng):
    p = np.repeat(pixel_centres(), n, axis=0)
    s = light.sample(p, rng.random((p.shape[0], 2)))
    e = (s.value * np.maximum(s.wi[:, 2], 0)[:, None]).reshape(RES * RES, n, 3).mean(axis=1)
    return (ALBEDO / np.pi * e).reshape(RES, RES, 3)


def matrix(loc, angle_x=0.0, scale=(1, 1, 1)):
    a = math.radians(angle_x)
    rot = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    m = np.eye(4)
    m[:3, :3] = rot @ np.diag(scale)
    m[:3, 3] = loc
    return m


CASES = [
    # name, Blender light type, matrix, Blender properties, Lamina light, Cycles samples
    ("point", "POINT", matrix((0.3, -0.2, 1.5)), dict(energy=100.0, shadow_soft_size=0.0),
     lambda m: PointLight(m, 100.0, [1, 1, 1]), 16),
    ("point_soft_falloff", "POINT", matrix((0.3, -0.2, 1.5)), dict(energy=100.0, shadow_soft_size=0.5, use_soft_falloff=True),
     lambda m: PointLight(m, 100.0, [1, 1, 1], radius=0.5, soft_falloff=True), 512),
    ("point_sphere", "POINT", matrix((0.3, -0.2, 1.5)), dict(energy=100.0, shadow_soft_size=0.5, use_soft_falloff=False),
     lambda m: PointLight(m, 100.0, [1, 1, 1], radius=0.5), 512),
    ("point_inside_sphere", "POINT", matrix((0.0, 0.0, 1.0)), dict(energy=100.0, shadow_soft_size=3.0, use_soft_falloff=False),
     lambda m: PointLight(m, 100.0, [1, 1, 1], radius=3.0), 256),
    ("spot_scaled", "SPOT", matrix((0.3, -0.2, 1.5), 20, (1.5, 1, 1)),
     dict(energy=100.0, shadow_soft_size=0.0, spot_size=math.radians(60), spot_blend=0.3),
     lambda m: SpotLight(m, 100.0, [1, 1, 1], math.radians(60), 0.3), 16),
    ("spot_sphere_close", "SPOT", matrix((0.1, 0.0, 0.6), 10),
     dict(energy=100.0, shadow_soft_size=0.45, spot_size=math.radians(40), spot_blend=0.5, use_soft_falloff=False),
     lambda m: SpotLight(m, 100.0, [1, 1, 1], math.radians(40), 0.5, radius=0.45), 512),
    ("sun_angle", "SUN", matrix((0, 0, 3), 30), dict(energy=3.0, angle=math.radians(10)),
     lambda m: SunLight(m, 3.0, [1, 1, 1], math.radians(10)), 64),
    ("area_scaled", "AREA", matrix((0.2, 0.1, 1.0), 15, (1.5, 0.7, 1)),
     dict(energy=50.0, shape="RECTANGLE", size=1.0, size_y=0.8),
     lambda m: AreaLight(m, "rectangle", 1.0, 0.8, 50.0, [1, 1, 1]), 512),
    ("ellipse", "AREA", matrix((0.2, 0.1, 1.0), 15, (1.5, 0.7, 1)),
     dict(energy=50.0, shape="ELLIPSE", size=1.0, size_y=0.8),
     lambda m: AreaLight(m, "ellipse", 1.0, 0.8, 50.0, [1, 1, 1]), 512),
    ("area_spread_40", "AREA", matrix((0.2, 0.1, 1.0), 15, (1.5, 0.7, 1)),
     dict(energy=50.0, shape="RECTANGLE", size=1.0, size_y=0.8, spread=math.radians(40)),
     lambda m: AreaLight(m, "rectangle", 1.0, 0.8, 50.0, [1, 1, 1], True, CyclesSpread(math.radians(40))), 512),
    ("area_spread_0", "AREA", matrix((0.2, 0.1, 1.0), 15, (1.5, 0.7, 1)),
     dict(energy=50.0, shape="RECTANGLE", size=1.0, size_y=0.8, spread=0.0),
     lambda m: CollimatedAreaLight(m, "rectangle", 1.0, 0.8, 50.0, [1, 1, 1]), 16),
    ("area_not_normalized", "AREA", matrix((0.2, 0.1, 1.0), 15, (1.5, 0.7, 1)),
     dict(energy=5.0, shape="SQUARE", size=0.5, normalize=False),
     lambda m: AreaLight(m, "square", 0.5, 0.5, 5.0, [1, 1, 1], False), 512),
]


def test_light_units_match_cycles(cycles):
    bpy, tmp = cycles
    from mathutils import Matrix
    rng = np.random.default_rng(50)
    sc = reset(bpy)
    add_plane_and_camera(bpy, sc)
    interior = np.zeros((RES, RES), bool)
    interior[1:-1, 1:-1] = True           # border pixels straddle the plane's edge
    report = []
    for name, kind, m, props, make, spp in CASES:
        data = bpy.data.lights.new(name, kind)
        for key, value in props.items():
            setattr(data, key, value)
        obj = bpy.data.objects.new(name, data)
        sc.collection.objects.link(obj)
        obj.matrix_world = Matrix(m.tolist())
        img = render(bpy, sc, tmp / f"{name}.exr", spp)
        bpy.data.objects.remove(obj)
        ref = lamina_radiance(make(m), 1 if make(m).is_delta else 2000, rng)
        lit = interior & (ref[..., 0] > 0.02 * ref[..., 0].max())
        a, b = img[..., 0][lit], ref[..., 0][lit]
        mean = float(a.sum() / b.sum())
        # standard error of the ratio of sums (delta method; pixels are independent)
        se = float(np.sqrt(np.sum((a - mean * b) ** 2) * a.size / (a.size - 1)) / b.sum())
        report.append(f"{name}: {mean:.4f} ± {se:.4f}")
        assert abs(mean - 1.0) <= 4 * se + 2e-5, report
    print("\n".join(report))


def test_environment_orientation_matches_cycles(cycles):
    """Camera rays into an environment texture, with and without a Mapping node rotation (Lamina:
    ``to_world`` = Rᵀ). Pixels within half a texel row of the poles are skipped: Cycles wraps the
    bilinear lookup across the poles, Lamina clamps."""
    bpy, tmp = cycles
    import OpenImageIO as oiio
    from mathutils import Euler
    h, w = 32, 64
    yy, xx = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    img = np.stack([1 + 0.8 * np.sin(2 * np.pi * xx), 1 + 0.8 * np.cos(np.pi * yy), 0.5 + xx * yy], -1)
    img[5:8, 40:44] = [5.0, 0.0, 0.0]
    path = tmp / "env.exr"
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(w, h, 3, oiio.FLOAT))
    out.write_image(img.astype(np.float32))
    out.close()
    for rotation in (None, (0.3, -0.2, 0.9)):
        sc = reset(bpy)
        nodes = sc.world.node_tree
        bg = nodes.nodes["Background"]
        bg.inputs["Strength"].default_value = 2.0
        tex = nodes.nodes.new("ShaderNodeTexEnvironment")
        tex.image = bpy.data.images.load(str(path))
        tex.image.colorspace_settings.name = "Non-Color"
        tex.image.use_half_precision = False          # Blender's default stores EXRs as half floats
        nodes.links.new(tex.outputs["Color"], bg.inputs["Color"])
        to_world = None
        if rotation is not None:
            mapping = nodes.nodes.new("ShaderNodeMapping")
            coords = nodes.nodes.new("ShaderNodeTexCoord")
            mapping.inputs["Rotation"].default_value = rotation
            nodes.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
            nodes.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
            to_world = np.eye(4)
            to_world[:3, :3] = np.array(Euler(rotation, "XYZ").to_matrix()).T
        env = EnvironmentMap(img, 2.0, to_world)
        cam = bpy.data.cameras.new("cam")
        cam.lens, cam.sensor_width = 50.0, 36.0
        co = bpy.data.objects.new("cam", cam)
        sc.collection.objects.link(co)
        sc.camera = co
        for euler in ((90, 0, -90), (90, 0, 0), (30, 0, 200), (150, 0, 45)):
            co.rotation_euler = [math.radians(a) for a in euler]
            bpy.context.view_layer.update()
            got = render(bpy, sc, tmp / "envcam.exr", 4)
            R = np.array(co.matrix_world)[:3, :3]
            c = (np.arange(RES) + 0.5) / RES * 2 - 1

            def lamina(dx, dy):
                X, Y = np.meshgrid(c + dx, -c + dy)
                d = np.stack([X * 18 / 50, Y * 18 / 50, -np.ones_like(X)], -1).reshape(-1, 3) @ R.T
                d /= np.linalg.norm(d, axis=1, keepdims=True)
                return env.eval_escaped(d).reshape(RES, RES, 3), d

            expected, d = lamina(0.0, 0.0)
            # Cycles jitters rays within its 0.01-pixel filter: allow the change of the radiance
            # over ±0.01 pixel, plus float32 rounding of the lookup.
            step = 0.01 * 2 / RES
            jitter = np.max([np.abs(lamina(sx * step, sy * step)[0] - expected)
                             for sx, sy in ((1, 0), (-1, 0), (0, 1), (0, -1))], axis=0)
            local = d @ env.to_world
            theta = np.degrees(np.arccos(np.clip(local[:, 2], -1, 1))).reshape(RES, RES)
            away_from_poles = (theta > 180 / h) & (theta < 180 - 180 / h)
            excess = np.abs(got - expected) - jitter - 1e-5 * expected
            # Almost every pixel agrees to the jitter bound; a rare Cycles filter sample lands
            # further out (seen: one pixel in 256 off by 1e-3). A wrong orientation or mapping
            # convention would be off by O(1) almost everywhere.
            assert np.mean(excess[away_from_poles] <= 0) > 0.98, (rotation, euler)
            assert np.all(np.abs(got / expected - 1)[away_from_poles] < 1e-2), (rotation, euler)
