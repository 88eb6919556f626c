"""The peer benchmark's Blender side (bpy 5.0.1): the converted scene has the settings the report
says were made equal, and Cycles renders the white furnace as physics says (the albedo-1 Lambert
strip exactly as bright as the world, the F = 1 rough conductor darker by its single-scattering
loss). The benchmark itself runs Cycles in a child process; here the same builder runs in-process."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks.peers import agree, convert
from benchmarks.peers.scenes import MAX_BOUNCES, RR_DEPTH, furnace

pytestmark = pytest.mark.blender

PEERS = Path(__file__).resolve().parent.parent / "benchmarks" / "peers"


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    bpy = pytest.importorskip("bpy")
    sys.path.insert(0, str(PEERS))
    try:
        import to_cycles
    finally:
        sys.path.remove(str(PEERS))
    tmp = tmp_path_factory.mktemp("peers")
    data = furnace(32)
    job = convert.prepare(data, tmp / "job")
    info = to_cycles.build(job, 2)
    return bpy, to_cycles, data, info, tmp


def test_settings_made_equal(built):
    bpy, _, _, info, _ = built
    sc = bpy.context.scene
    c = sc.cycles
    assert (c.pixel_filter_type, c.filter_width) == ("BLACKMAN_HARRIS", 1.5)   # the same width
    assert c.max_bounces == c.diffuse_bounces == c.glossy_bounces == c.transmission_bounces == MAX_BOUNCES
    assert c.min_light_bounces == RR_DEPTH - 2      # Cycles' kernel min_bounce = min_light_bounces + 1
    assert c.sample_clamp_direct == 0 and c.sample_clamp_indirect == 0 and c.blur_glossy == 0
    assert not c.use_denoising and not c.use_adaptive_sampling and c.caustics_reflective and c.caustics_refractive
    assert sc.render.threads_mode == "FIXED" and sc.render.threads == 2 and c.device == "CPU"
    assert info["camera_frame_error"] < 1e-6 and abs(info["pixel_aspect"] - 1) < 1e-9
    gold = bpy.data.materials["gold"].node_tree.nodes["Metallic BSDF"]
    assert gold.distribution == "GGX" and gold.fresnel_type == "PHYSICAL_CONDUCTOR"
    assert math.isclose(gold.inputs["Roughness"].default_value, math.sqrt(0.2), rel_tol=1e-6)
    assert all(o.shadow_terminator_geometry_offset == 0 for o in bpy.data.objects if o.type == "MESH")


def ggx_albedo(alpha: float, cos_o: float, n: int = 700) -> float:
    """Directional albedo of a single-scattering GGX reflector with F = 1 and the height-correlated
    Smith term (what plain GGX in Cycles is), by midpoint quadrature over the hemisphere."""
    mu = (np.arange(n) + 0.5) / n
    phi = (np.arange(n) + 0.5) / n * 2 * np.pi
    m, p = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - m * m)
    wi = np.stack([s * np.cos(p), s * np.sin(p), m], -1)
    wo = np.array([math.sqrt(1 - cos_o ** 2), 0.0, cos_o])
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)

    def lam(c):
        return (-1 + np.sqrt(1 + alpha ** 2 * (1 - c * c) / (c * c))) / 2
    ch = h[..., 2]
    d = 1 / (np.pi * alpha ** 2 * ch ** 4 * (1 + (1 - ch ** 2) / (ch ** 2 * alpha ** 2)) ** 2)
    f_cos = d / (1 + lam(wi[..., 2]) + lam(cos_o)) / (4 * cos_o)
    return float(f_cos.mean() * 2 * np.pi)


def test_white_furnace_in_cycles(built):
    bpy, to_cycles, data, _, tmp = built
    import OpenImageIO as oiio
    path = tmp / "furnace.exr"
    to_cycles.render(path, 64, 3)
    inp = oiio.ImageInput.open(str(path))
    img = np.asarray(inp.read_image(0, 0, 0, 3, oiio.FLOAT), dtype=np.float64).reshape(32, 32, 3)
    inp.close()
    from backend.scene.loader import load_scene_data
    s = load_scene_data(data)
    lab, names = agree.labels(data, s.soup.vertices, s.soup.object_id)
    world = img[lab == names.index("world")]
    assert np.allclose(world, 1.0, atol=1e-6)                      # the world seen directly: exact
    # The F = 1 strip (α 0.3) loses what single-scattering GGX loses; it is seen at view angles
    # between those of its nearest and farthest corner (its albedo falls with the angle here).
    cam = np.array(data["camera"]["to_world"])[:3, 3]
    corners = np.array([[x, y, 0.0] for x in (0.3, 0.9) for y in (-0.8, 0.8)])
    cos_view = cam[2] / np.linalg.norm(cam - corners, axis=1)
    e_lo, e_hi = ggx_albedo(0.3, cos_view.min()), ggx_albedo(0.3, cos_view.max())
    assert 0.75 < e_lo < e_hi < 0.9            # far from 1: Multiscatter GGX would be caught
    for strip, lo, hi in (("lambert strip", 1.0, 1.0), ("mirror strip", e_lo, e_hi)):
        px = img[lab == names.index(strip)].mean(axis=1)
        mean, se = px.mean(), px.std(ddof=1) / math.sqrt(px.size)
        assert lo - 4 * se <= mean <= hi + 4 * se, (strip, mean, se)


def test_principled_materials_and_sun_in_cycles(built, tmp_path):
    # Runs last: it replaces the furnace scene the module's fixture built.
    bpy, to_cycles, *_ = built
    from benchmarks.peers.scenes import EVERYDAY, everyday
    to_cycles.build(convert.prepare(everyday(16), tmp_path / "everyday", principled=EVERYDAY), 2)
    inputs = {"base_color": "Base Color", "metallic": "Metallic", "roughness": "Roughness",
              "transmission": "Transmission Weight", "coat_weight": "Coat Weight"}
    for name, p in EVERYDAY.items():
        node = bpy.data.materials[name].node_tree.nodes["Principled BSDF"]
        assert node.distribution == "GGX", name
        for key, value in p.items():
            got = node.inputs[inputs[key]].default_value
            want = (*value, 1.0) if isinstance(value, tuple) else (value,)
            np.testing.assert_allclose(tuple(got) if isinstance(value, tuple) else (got,), want, rtol=1e-6)
        # Everything the settings do not name stays at Blender's default.
        assert math.isclose(node.inputs["Coat Roughness"].default_value, 0.03, rel_tol=1e-6)
        assert node.inputs["IOR"].default_value == 1.5 and node.inputs["Specular IOR Level"].default_value == 0.5
    suns = [o for o in bpy.data.objects if o.type == "LIGHT"]
    assert len(suns) == 1 and suns[0].data.type == "SUN" and not suns[0].visible_camera
    assert suns[0].data.energy == 3.0 and math.isclose(suns[0].data.angle, math.radians(5.0), rel_tol=1e-6)


def test_sun_irradiance_in_cycles(built, tmp_path):
    # A Lambertian plane (albedo ρ) under a sun of strength E (irradiance, W/m²) whose direction
    # makes 60° with the normal, direct light only: L = ρ E cos 60° / π at every pixel. For a sun
    # of angular diameter 5° this is exact too (the integral of the cosine over a cap is the
    # cosine at its centre times the cap's projected area), so strength, angle and direction of
    # the converted light are all checked.
    bpy, to_cycles, *_ = built
    import OpenImageIO as oiio

    from benchmarks.peers.scenes import _scene
    from benchmarks.scenes import _quad, look_at
    theta = math.radians(60.0)
    sun = {"type": "sun", "strength": 2.0, "angle": 5.0,
           "to_world": look_at((math.sin(theta), 0.0, math.cos(theta)), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))}
    camera = {"type": "perspective", "to_world": look_at((0, 0, 3), (0, 0, 0), up=(0, 1, 0)),
              "frame": [[0.2, 0.2, -1], [0.2, -0.2, -1], [-0.2, -0.2, -1], [-0.2, 0.2, -1]]}
    data = _scene(8, camera, {"plane": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}},
                  {"plane": _quad([-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0])},
                  [{"name": "plane", "mesh": "plane", "materials": ["plane"]}], [sun])
    data["render"]["max_bounces"] = 0
    to_cycles.build(convert.prepare(data, tmp_path / "sun"), 2)
    path = tmp_path / "sun.exr"
    to_cycles.render(path, 16, 1)
    inp = oiio.ImageInput.open(str(path))
    img = np.asarray(inp.read_image(0, 0, 0, 3, oiio.FLOAT), dtype=np.float64).reshape(8, 8, 3)
    inp.close()
    want = 0.5 * 2.0 * math.cos(theta) / math.pi
    mean, se = img.mean(), img.std(ddof=1) / math.sqrt(img.size)
    assert abs(mean - want) <= 4 * se + 1e-5 * want, (mean, want, se)
