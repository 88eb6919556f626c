"""Caustics traced from the lights (kernels/caustics.py, backend/caustics.py): the photons take
the paths light → smooth glass, mirror or sharp glossy surface → a surface the camera sees, and
the path tracer drops the same paths, so the image must not change — compared with the path
tracer alone (caustic_photons 0), region by region and over the whole image, within the spread
of independent renders (the photons' noise is not in the film's per-pixel variance) — while the
noise of the caustics falls. Also: the camera projection the splats use is the inverse of the
camera's rays, and the scenes the method cannot serve fall back to the path tracer with a
reason."""
from __future__ import annotations

import copy

import numpy as np
import pytest
from scipy.stats import t as student_t

from backend.caustics import plan_caustics
from backend.geometry.accel import Accelerator
from backend.integrator import PathTracer
from backend.kernels.camera import camera_vector, generate
from backend.kernels.caustics import project
from backend.scene.loader import load_scene_data
from render_util import quad, render, scene
from stats_util import sidak

GLASS = {"type": "dielectric", "ior": 2.0, "roughness": 0.0}     # index 2: a strong mirror too
MIRROR = {"type": "conductor", "metal": "Ag", "roughness": 0.0}
DIFFUSE = {"type": "diffuse", "color": [0.7, 0.7, 0.7]}
GLOSSY = {"type": "conductor", "metal": "Cu", "roughness": 0.3}
ROUGH_GLASS = {"type": "dielectric", "ior": 1.5, "roughness": 0.9}
# Smooth glass that transmits nothing: its light on the floor is its mirror's alone, which the
# glass also connects to the lights every sample (kernels/integrator.py ``_probe_reflection``);
# on the photons' paths that connection must stay off, or those caustics count twice.
MIRRORING_GLASS = {"type": "dielectric", "ior": 2.4, "roughness": 0.0, "transmission_color": [0.0, 0.0, 0.0]}


def _scene(spp: int, seed: int, photons: float, caster=GLASS, floor=DIFFUSE, size: int = 24,
           sun_angle: float = 30.0, camera: dict | None = None, render_extra: dict | None = None,
           lights: list | None = None, emitter: str | None = None) -> dict:
    """A ball of ``caster`` over a ``floor`` under a wide sun and a small area light, both beside
    the camera's side of the ball, so the caustics lie in view; a dim world."""
    materials = {"caster": caster, "floor": floor}
    meshes = {"ball": {"shape": "sphere", "radius": 0.5, "segments": 48},
              "floor": quad([0, 0, 0], [2.0, 0, 0], [0, 2.0, 0])}
    objects = [{"name": "ball", "mesh": "ball", "materials": ["caster"],
                "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.6], [0, 0, 0, 1]]},
               {"name": "floor", "mesh": "floor", "materials": ["floor"]}]
    if lights is None:
        lights = [{"type": "sun", "strength": 3.0, "angle": sun_angle,
                   "to_world": [[1, 0, 0, 0], [0, 0.8, 0.6, 0], [0, -0.6, 0.8, 10], [0, 0, 0, 1]]},
                  {"type": "area", "shape": "rectangle", "size": 0.8, "size_y": 0.5, "power": 60.0,
                   "to_world": [[1, 0, 0, 0.0], [0, 1, 0, 1.2], [0, 0, 1, 2.0], [0, 0, 0, 1]]}]
    cam = camera or {"type": "perspective",
                     "to_world": [[1, 0, 0, 0], [0, 0.6, -0.8, -3.2], [0, 0.8, 0.6, 3.0], [0, 0, 0, 1]],
                     "frame": [[0.45, 0.45, -1], [0.45, -0.45, -1], [-0.45, -0.45, -1], [-0.45, 0.45, -1]]}
    if emitter is not None:
        # an emissive surface instead of the lights: a small bulb (both faces emit) or a panel
        # facing down (its front only), where the area light was
        lights = []
        materials["glow"] = {"type": "emission", "color": [1.0, 0.9, 0.8], "strength": 10.0}
        at = [[1, 0, 0, 0.0], [0, 1, 0, 1.2], [0, 0, 1, 2.0], [0, 0, 0, 1]]
        if emitter == "bulb":
            # large enough that path tracing, the reference here, finds it through the glass
            # often (at radius 0.15 its dim glow on the floor came only from rare fireflies:
            # 12 renders of 128 samples saw none in most regions, so their spread said nothing)
            meshes["glow"] = {"shape": "sphere", "radius": 0.35, "segments": 16}
        else:
            materials["glow"]["emission_sides"] = "front"
            meshes["glow"] = quad([0, 0, 0], [0.25, 0, 0], [0, -0.2, 0])     # a × b points down
        objects.append({"name": "glow", "mesh": "glow", "materials": ["glow"], "to_world": at})
    settings = {"spp": spp, "max_bounces": 6, "seed": seed, "caustic_photons": photons}
    settings.update(render_extra or {})
    return scene(size, size, cam, materials, meshes, objects, lights,
                 world={"type": "constant", "color": [0.2, 0.25, 0.3]}, render=settings)


def _renders(seeds: int, spp: int, photons: float, apart: bool = False, **shape) -> np.ndarray:
    return np.stack([render(_apart(_scene(spp, 100 + s, photons, **shape)) if apart else
                            _scene(spp, 100 + s, photons, **shape)).film.combined()[..., :3]
                     for s in range(seeds)])


def _apart(data: dict) -> dict:
    """A second ball of the caster, up towards the sun and the lamp: photons aim at each one's
    sphere, and where one sphere's cross-section (or cone, from the lamp, whose corner lies
    inside it) overlaps the other's both densities count (kernels/caustics.py
    ``_line_density``, ``_cone_density``)."""
    second = copy.deepcopy(data["objects"][0])
    second["name"] = "ball 2"
    second["to_world"] = [[0.9, 0, 0, 0.3], [0, 0.9, 0, 0.8], [0, 0, 0.9, 1.6], [0, 0, 0, 1]]
    data["objects"].insert(1, second)
    return data


def _region_sums(images: np.ndarray, blocks: int) -> np.ndarray:
    """(renders, regions + 1): each render's sum over the RGB of a blocks × blocks region, and
    of the whole image (a bias spread thinly over many regions shows there)."""
    n, h, w, _ = images.shape
    return np.stack([images[:, by * h // blocks:(by + 1) * h // blocks, bx * w // blocks:(bx + 1) * w // blocks]
                     .sum(axis=(1, 2, 3)) for by in range(blocks) for bx in range(blocks)]
                    + [images.sum(axis=(1, 2, 3))], axis=1)


def _assert_agree(a: np.ndarray, b: np.ndarray, label: str) -> None:
    """Region sums (``_region_sums``) of two sets of independent renders have the same means:
    |z| below a t-based Šidák bound at 1 % over the lit regions."""
    n = a.shape[0]
    se = np.sqrt(a.var(axis=0, ddof=1) / n + b.var(axis=0, ddof=1) / b.shape[0])
    lit = se > 0
    z = np.abs(a.mean(axis=0) - b.mean(axis=0))[lit] / se[lit]
    bound = student_t.isf(sidak(0.01, int(lit.sum())) / 2, n - 1)
    assert z.max() < bound, f"{label}: region z {np.round(z, 2)} (bound {bound:.2f})"


# The ball's material, the floor's, and whether the path tracer alone converges fast enough here:
# a glass ball (both caustics: the refracted one, and its mirror's, which smooth glass also
# connects to the lights it mirrors — that connection must skip the photons' paths), a mirror
# ball, and receivers that are glossy or transmit.
# Sharp glossy casters (α ≤ backend/caustics.py CAUSTIC_ALPHA): a polished metal and a clear
# coat over a diffuse body (the closed form), which the photons pass on by sampling them.
POLISHED = {"type": "conductor", "metal": "Au", "roughness": 0.02}
GLOSSY_GOLD = {"type": "conductor", "metal": "Au", "roughness": 0.08}     # a metal: CAUSTIC_ALPHA_METAL
COATED = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.01},
                                            {"type": "diffuse", "color": [0.1, 0.3, 0.6]}],
          "media": [{"thickness": 1.0, "sigma_t": 0.0}]}
# Samples per pixel: the glossy casters' caustics are fainter. A caster vertex that kept its
# light samples of the covered lights (kernels/integrator.py ``in_chain``) counts those paths
# twice: at α ≤ 0.02 multiple importance sampling gives such samples almost no weight against
# the lobe's own (polished metal, 512 spp, 12 seeds: whole image z −1.7 under this 30° sun), but
# the glossy gold (α 0.08, a caster as a metal) shows it: region z up to 6.8 against a bound of
# about 4.5 with them left in (measured 2026-12-08).
CASES = {"glass on diffuse": (GLASS, DIFFUSE, 128), "mirror on diffuse": (MIRROR, DIFFUSE, 128),
         "mirroring glass on diffuse": (MIRRORING_GLASS, DIFFUSE, 128),
         "polished metal on diffuse": (POLISHED, DIFFUSE, 512), "coat on glossy metal": (COATED, GLOSSY, 512),
         "glass on glossy metal": (GLASS, GLOSSY, 128), "mirror on rough glass": (MIRROR, ROUGH_GLASS, 128),
         "glossy gold on diffuse": (GLOSSY_GOLD, DIFFUSE, 256)}


@pytest.mark.parametrize("case", list(CASES) + ["two glass balls"])
def test_light_traced_caustics_keep_the_image(case):
    caster, floor, spp = CASES.get(case, (GLASS, DIFFUSE, 128))
    apart = case == "two glass balls"
    seeds, blocks = 12, 4
    a = _region_sums(_renders(seeds, spp, 0.0, apart, caster=caster, floor=floor), blocks)
    b = _region_sums(_renders(seeds, spp, 1.0, apart, caster=caster, floor=floor), blocks)
    _assert_agree(a, b, case)


# Point lights with a radius, as Blender's point and spot lights have (kernels/caustics.py
# ``_emit``: lines within the radius of the centre): a soft-falloff disk (Blender's default), a
# sphere, and a spot with a soft edge and an IES profile whose peak is off its axis, each beside
# the glass ball where the area light was. The soft light is large (radius 0.8 at 1.3–2.3 from
# the ball) so that the disk it turns towards each point differs from a sphere: without the
# photon kernel's check of that disk, region z 15 (measured). Without the spot's and the
# profile's factor on the photons, z 11; with the aiming cone not grown by the radius, z 15.
_LAMP = [[1, 0, 0, 0.0], [0, 1, 0, 1.2], [0, 0, 1, 2.0], [0, 0, 0, 1]]
_IES = "IESNA:LM-63-2002\nTILT=NONE\n1 1000 1 3 1 1 2 0.1 0.1 0\n1 1 100\n0 30 90\n0\n600 1000 100\n"
LAMPS = {
    "soft point light": {"type": "point", "power": 150.0, "radius": 0.8, "soft_falloff": True, "to_world": _LAMP},
    "sphere light": {"type": "point", "power": 150.0, "radius": 0.3, "to_world": _LAMP},
    "spot light with IES": {"type": "spot", "power": 300.0, "radius": 0.2, "soft_falloff": True, "spot_size": 70.0,
                            "spot_blend": 0.5, "ies": {"data": _IES},
                            "to_world": [[1, 0, 0, 0.0], [0, 0.8, 0.6, 1.2], [0, -0.6, 0.8, 2.0], [0, 0, 0, 1]]},
}
# Radius 0 (a delta light): through glass the path tracer never finds it (below), off the glossy
# gold it does, by its light samples there.
DELTA_POINT = {"type": "point", "power": 150.0, "to_world": _LAMP}
DELTA_SPOT = {"type": "spot", "power": 300.0, "spot_size": 70.0, "spot_blend": 0.5, "ies": {"data": _IES},
              "to_world": LAMPS["spot light with IES"]["to_world"]}
DELTA_SUN = {"type": "sun", "strength": 3.0, "angle": 0.0,
             "to_world": [[1, 0, 0, 0], [0, 0.8, 0.6, 0], [0, -0.6, 0.8, 10], [0, 0, 0, 1]]}
# Directional area lights (a profile over the angle to their normal: Blender's spread, and
# Lamina's cutoff and beam width), tilted towards the ball
_TILTED = [[1, 0, 0, 0.0], [0, 0.8, 0.6, 1.2], [0, -0.6, 0.8, 2.0], [0, 0, 0, 1]]
LAMPS["area light with a spread"] = {"type": "area", "shape": "rectangle", "size": 0.8, "size_y": 0.5,
                                     "power": 60.0, "spread": 40.0, "to_world": _TILTED}
LAMPS["area light with a beam"] = {"type": "area", "shape": "square", "size": 0.8, "power": 60.0,
                                   "cutoff_angle": 50.0, "beam_width": 30.0, "to_world": _TILTED}
LAMP_CASES = {**{k: (v, GLASS) for k, v in LAMPS.items()},
              "delta point light on glossy gold": (DELTA_POINT, GLOSSY_GOLD),
              "delta spot light with IES on glossy gold": (DELTA_SPOT, GLOSSY_GOLD),
              "sun of angle 0 on glossy gold": (DELTA_SUN, GLOSSY_GOLD)}


@pytest.mark.parametrize("case", list(LAMP_CASES))
def test_lamp_caustics_keep_the_image(case):
    """Each lamp alone over the ball: path traced against light traced, region by region."""
    light, caster = LAMP_CASES[case]
    lights = [light]
    seeds, blocks = 12, 4
    spp = 128 if caster is GLASS else 256
    a = _region_sums(_renders(seeds, spp, 0.0, lights=lights, caster=caster), blocks)
    b = _region_sums(_renders(seeds, spp, 1.0, lights=lights, caster=caster), blocks)
    _assert_agree(a, b, case)
    # light traced, and the regions' variance falls (measured 0.53 for the large soft light,
    # whose blurred caustic the path tracer finds well enough, 0.18 and 0.14 for the others)
    sc = load_scene_data(_scene(1, 0, 1.0, lights=lights, caster=caster), "<test>")
    assert PathTracer(sc, Accelerator(sc.soup)).caustics.active
    assert b.var(axis=0, ddof=1)[:-1].sum() < 0.7 * a.var(axis=0, ddof=1)[:-1].sum()


@pytest.mark.parametrize("emitter", ["bulb", "panel"])
def test_emissive_surface_caustics_keep_the_image(emitter):
    """Emissive triangles (a mesh light) through the glass ball: path traced (its rays hit the
    emitter) against light traced, as for the lights above."""
    seeds, blocks = 12, 4
    a = _region_sums(_renders(seeds, 128, 0.0, emitter=emitter), blocks)
    b = _region_sums(_renders(seeds, 128, 1.0, emitter=emitter), blocks)
    _assert_agree(a, b, emitter)
    sc = load_scene_data(_scene(1, 0, 1.0, emitter=emitter), "<test>")
    assert PathTracer(sc, Accelerator(sc.soup)).caustics.active
    assert b.var(axis=0, ddof=1)[:-1].sum() < 0.7 * a.var(axis=0, ddof=1)[:-1].sum()


@pytest.mark.parametrize("delta, small", [(DELTA_POINT, dict(DELTA_POINT, radius=0.01)),
                                          (DELTA_SUN, dict(DELTA_SUN, angle=0.2))], ids=["point", "sun"])
def test_a_delta_light_through_glass_is_the_limit_of_small_ones(delta, small):
    """The caustic of a radius-0 point light (a sun of angle 0) through the glass ball, which path
    tracing cannot find, against that of a sphere light of radius 0.01 and the same power (a sun
    of angle 0.2°): path tracing's agreement with those lights' photons is tested above and in
    the cases of the sun and area light; the irradiance of each pair differs by about 1e-4 or
    less here. Independent seeds for each."""
    seeds, blocks = 12, 4
    a = _region_sums(np.stack([render(_scene(16, 100 + s, 4.0, lights=[delta])).film.combined()[..., :3]
                               for s in range(seeds)]), blocks)
    b = _region_sums(np.stack([render(_scene(16, 200 + s, 4.0, lights=[small])).film.combined()[..., :3]
                               for s in range(seeds)]), blocks)
    _assert_agree(a, b, "delta light")
    # and the caustic is there: without photons (as before) the image is darker (measured: the
    # whole image 7.6 % for the point light, the two regions under the ball 28 % and 18 %; 3.8 %
    # for the sun)
    c = _region_sums(np.stack([render(_scene(16, 100 + s, 0.0, lights=[delta])).film.combined()[..., :3]
                               for s in range(4)]), blocks)
    assert a.mean(axis=0)[-1] > c.mean(axis=0)[-1] * 1.02


def test_caustic_noise_falls():
    """Where the glass focuses the sun and the lamp onto the floor, the spread of independent
    renders falls at least 5× in variance (measured: 98 → 1.3 and 250 → 0.5 in the two
    brightest caustic blocks at 32², 64 spp)."""
    a = _renders(8, 16, 0.0)
    b = _renders(8, 16, 0.25)
    va, vb = a.var(axis=0, ddof=1).sum(axis=-1), b.var(axis=0, ddof=1).sum(axis=-1)
    # the floor in front of the ball, where both caustics land (rows below the ball's image)
    rows = slice(15, 21)
    assert vb[rows].sum() < 0.2 * va[rows].sum(), (va[rows].sum(), vb[rows].sum())


def test_the_same_image_for_any_worker_count():
    data = _scene(8, 3, 0.5)
    one = render(data, workers=1).film.combined()
    two = render(data, workers=2).film.combined()
    assert np.array_equal(one, two)


def test_projection_inverts_the_camera_rays():
    """``project`` returns the film position a camera ray came from, and J, the pixels per
    steradian around it (checked against the solid angle of a small film square)."""
    data = _scene(1, 0, 1.0, size=24)
    data["camera"]["to_world"] = [[0.8, 0.0, 0.6, 0.3], [0.6, 0.0, -0.8, -3.0], [0.0, 1.0, 0.0, 0.9], [0, 0, 0, 1]]
    data["camera"]["frame"] = [[0.5, 0.2, -1], [0.5, -0.4, -1], [-0.3, -0.4, -1], [-0.3, 0.2, -1]]   # shifted
    sc = load_scene_data(copy.deepcopy(data), "<test>")
    tracer = PathTracer(sc, Accelerator(sc.soup))
    proj = tracer.caustics.tables.proj
    cam = camera_vector(sc.camera)
    rng = np.random.default_rng(5)
    h = 1e-4
    for s, t in rng.uniform(0.05, 0.95, (20, 2)):
        o, d, _, _ = generate(cam, s, t, False, 0.5, 0.5)
        x = np.add(o, 2.7 * np.asarray(d))
        ps, pt, J, r, reach = project(proj, tuple(x))
        assert abs(ps - s) < 1e-9 and abs(pt - t) < 1e-9
        assert abs(r - 2.7) < 1e-9 and 0.0 < reach <= r
        # solid angle of the film square [s, s+h] × [t, t+h] (h² W H pixels)
        c = [np.asarray(generate(cam, s + i * h, t + j * h, False, 0.5, 0.5)[1]) for i, j in ((0, 0), (1, 0), (0, 1))]
        omega = np.linalg.norm(np.cross(c[1] - c[0], c[2] - c[0]))
        assert J == pytest.approx(h * h * 24 * 24 / omega, rel=1e-3)


@pytest.mark.parametrize("change, reason", [
    ({"render": {"caustic_photons": 0.0}}, "caustic_photons is 0"),
    ({"render": {"clamp": 5.0}}, "Clamp Indirect"),
    ({"camera": {"dof": {"focus_distance": 3.0, "aperture_radius": 0.05}}}, "depth of field"),
    ({"caster": DIFFUSE}, "no smooth glass, mirror or sharp glossy surface"),
    ({"caster": ROUGH_GLASS}, "no smooth glass, mirror or sharp glossy surface"),
    ({"no_lights": True}, "no light the photons can leave"),
])
def test_scenes_it_cannot_serve_are_path_traced(change, reason):
    data = _scene(1, 0, 1.0, caster=change.get("caster", GLASS), sun_angle=change.get("sun_angle", 30.0),
                  render_extra=change.get("render"))
    data["camera"].update(change.get("camera", {}))
    if change.get("no_lights"):
        data["lights"] = []
    sc = load_scene_data(data, "<test>")
    tracer = PathTracer(sc, Accelerator(sc.soup))
    assert not tracer.caustics.active and reason in tracer.caustics.reason
    assert tracer.settings.caustic_light.size == 0


def test_a_scene_it_serves_says_so():
    sc = load_scene_data(_scene(1, 0, 1.0), "<test>")
    plan = plan_caustics(sc, PathTracer(sc, Accelerator(sc.soup)))
    # the sun and the area light; the world (the last light) stays with the path tracer
    assert plan.active and plan.reason == "" and plan.light.tolist() == [True, True, False]


@pytest.mark.parametrize("caster, expect", [
    ({"type": "conductor", "metal": "Au", "roughness": 0.1}, True),        # a metal up to α 0.1
    ({"type": "conductor", "metal": "Au", "roughness": 0.12}, False),
    ({"type": "dielectric", "ior": 1.5, "roughness": 0.02}, True),          # others up to α 0.02
    ({"type": "dielectric", "ior": 1.5, "roughness": 0.05}, False),
])
def test_which_glossy_surfaces_are_casters(caster, expect):
    sc = load_scene_data(_scene(1, 0, 1.0, caster=caster), "<test>")
    plan = plan_caustics(sc, PathTracer(sc, Accelerator(sc.soup)))
    assert plan.active == expect, plan.reason


def test_a_crop_gets_no_caustic_outside_it():
    """The splats stay inside a crop, as the camera samples do; inside it the caustic is there."""
    data = _scene(4, 1, 1.0)
    data["film"]["crop"] = [4, 14, 20, 22]          # the floor in front of the ball, its caustics
    film = render(data).film
    img = film.combined()
    inside = np.zeros(img.shape[:2], bool)
    inside[14:22, 4:20] = True
    assert film.photons > 0 and np.all(img[~inside] == 0.0)
    assert film.caustic.reshape(img.shape)[inside].sum() > 0.0


def test_a_photon_never_picks_an_entry_of_probability_zero():
    """``_pick`` (a binary search) against its definition: the first k with u < cdf[k + 1]."""
    from backend.kernels.caustics import _pick
    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 7, 300):
        w = rng.random(n) * (rng.random(n) < 0.6)
        w[rng.integers(n)] = 1.0
        cdf = np.concatenate([[0.0], np.cumsum(w) / w.sum()])
        cdf[-1] = 1.0
        us = np.concatenate([rng.random(200), cdf[:-1], [np.nextafter(1.0, 0.0)]])
        for u in us[us < 1.0]:                      # u is in [0, 1)
            k, p = _pick(cdf, u)
            want = int(np.flatnonzero(u < cdf[1:])[0])
            assert k == want and p == cdf[k + 1] - cdf[k] and p > 0.0


def test_photon_flux_reaching_each_caster():
    """Whatever sphere a photon was aimed at, the flux arriving at each caster sphere is the
    light's: a sun gives L Ω π R² to every sphere (its irradiance over the cross-section), an
    area light ∫∫ L cos dω dA over the cone each sphere fills (estimated here independently,
    sphere by sphere). The two spheres of the scene overlap as seen from both lights, so a
    photon's density must count both (kernels/caustics.py ``_line_density``, ``_cone_density``)."""
    from backend.kernels.caustics import _emit
    from backend.kernels.lights import area as A
    from backend.kernels.lights import sun as SUN
    from backend.kernels.rng import path_key
    sc = load_scene_data(_apart(_scene(1, 0, 1.0)), "<test>")
    tracer = PathTracer(sc, Accelerator(sc.soup))
    CT, LT, TX = tracer.caustics.tables, tracer.light_table, tracer.tables()[2]
    P, spheres = LT.params, CT.spheres
    assert spheres.shape[0] == 2
    n, m = 40000, 400000
    rng = np.random.default_rng(3)
    for li in CT.lights:
        only = CT._replace(lights=np.array([li]), cdf=np.array([0.0, 1.0]))
        arriving = np.zeros((n, 2))
        for i in range(n):
            o, d, phi, _ = _emit(LT, TX, only, np.uint64(path_key(7, int(li), i)))
            e = spheres[:, :3] - np.asarray(o)
            a = e @ np.asarray(d)
            arriving[i] = phi[1] * ((a > 0) & ((e * e).sum(axis=1) - a * a <= spheres[:, 3] ** 2))
        got, se = arriving.mean(axis=0), arriving.std(axis=0) / np.sqrt(n)
        if LT.kind[li] == SUN.SUN:
            want = P[li, SUN.S_RADIANCE + 1] * 2 * np.pi * P[li, SUN.S_OMC] * np.pi * spheres[:, 3] ** 2
            want_se = np.zeros(2)
        else:
            # a plain rectangle: the same radiance towards every direction in front
            L = A.radiance(P, LT.iparams, li, 0.5)[1]
            c, u, v, nrm = (P[li, A.A_CENTER + 3 * j:A.A_CENTER + 3 * j + 3] for j in range(4))
            area = 4 * P[li, A.A_HALF_U] * P[li, A.A_HALF_V]
            y = (c + (2 * rng.random((m, 1)) - 1) * P[li, A.A_HALF_U] * u
                 + (2 * rng.random((m, 1)) - 1) * P[li, A.A_HALF_V] * v)
            want, want_se = np.zeros(2), np.zeros(2)
            for k in range(2):
                to = spheres[k, :3] - y
                dist = np.linalg.norm(to, axis=1)
                axis = to / dist[:, None]
                inside = dist <= spheres[k, 3]
                omc = np.where(inside, 2.0, 1 - np.sqrt(np.maximum(1 - (spheres[k, 3] / dist) ** 2, 0)))
                axis[inside] = [0.0, 0.0, 1.0]
                cos_t = 1 - rng.random(m) * omc
                phi_ = 2 * np.pi * rng.random(m)
                t1 = np.cross(axis, [1.0, 0.0, 0.0])
                t1 /= np.linalg.norm(t1, axis=1)[:, None]
                t2 = np.cross(axis, t1)
                sin_t = np.sqrt(np.maximum(1 - cos_t ** 2, 0))
                d = (sin_t * np.cos(phi_))[:, None] * t1 + (sin_t * np.sin(phi_))[:, None] * t2 + cos_t[:, None] * axis
                vals = L * np.maximum(d @ nrm, 0.0) * 2 * np.pi * omc * area
                want[k], want_se[k] = vals.mean(), vals.std() / np.sqrt(m)
        z = np.abs(got - want) / np.sqrt(se ** 2 + want_se ** 2)
        assert np.all(z < 4.0), (int(LT.kind[li]), got, want, z)


def test_area_light_photons_start_off_the_emitter():
    """A lamp often lies on a ceiling or panel: its photons start a surface offset off it, on its
    emitting side, so they do not hit that surface at distance 0."""
    from backend.kernels.caustics import _emit
    from backend.kernels.lights import area as A
    from backend.kernels.rng import path_key
    sc = load_scene_data(_scene(1, 0, 1.0), "<test>")
    tracer = PathTracer(sc, Accelerator(sc.soup))
    CT, LT, TX = tracer.caustics.tables, tracer.light_table, tracer.tables()[2]
    li = int(CT.lights[1])
    assert LT.kind[li] == A.AREA
    only = CT._replace(lights=np.array([li]), cdf=np.array([0.0, 1.0]))
    c, n = LT.params[li, A.A_CENTER:A.A_CENTER + 3], LT.params[li, A.A_N:A.A_N + 3]
    heights = [(np.asarray(_emit(LT, TX, only, np.uint64(path_key(5, 0, i)))[0]) - c) @ n for i in range(200)]
    assert min(heights) > 1e-7 and max(heights) < 1e-4
