"""The peer-benchmark scenes, each described **once** as a Lamina scene dict.

Lamina loads the dict directly; Cycles gets it through ``convert.py`` (the same triangles, taken
from Lamina's own loader) and ``to_cycles.py``. Only features the converter supports are used:
meshes (built-in shapes and inline quads), diffuse / conductor with explicit complex IOR per RGB /
dielectric (rough or smooth), the two-interface coat (layered scene only), area lights with
``spread``, a point light with an IES profile, a sun, a constant world and a perspective camera.

Two scenes describe some materials as Blender's **Principled BSDF** instead (``PeerScene.principled``,
material name → Principled settings): Cycles renders those names as a Principled BSDF node with the
settings, Lamina renders the scene dict's material. In "everyday" the scene dict's material is what
the add-on exports for the very same settings (``addon/export/principled.py``), so both renderers
render the same .blend as an artist would build it; in "presets" Lamina renders layered presets
and the Principled settings are hand-made approximations for Cycles (different materials).

Settings shared by every scene (see docs/benchmarks.md, "Lamina vs Cycles"): GGX with the
height-correlated Smith masking (Lamina's default, what Cycles uses), Blender's default pixel
filter (``FILM_FILTER``, the same width in both), ``max_bounces`` = ``MAX_BOUNCES``, Russian roulette from
``RR_DEPTH``, no clamping. Conductors carry Lamina's own measured RGB (eta, k) explicitly, so the
converter passes the very same numbers to Cycles' Physical Conductor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

from backend.materials.metals import metal_ior

from ..everyday import principled_module
from ..scenes import IES_DIR, _m, _quad, look_at, perspective

#: Bounces for both renderers (Lamina ``max_bounces`` has Cycles' meaning: 0 = direct light only).
MAX_BOUNCES = 8
#: Lamina's default Russian-roulette depth; Cycles gets ``min_light_bounces`` = RR_DEPTH − 2,
#: which makes the first surface subject to roulette the same (to_cycles.py explains the indexing).
RR_DEPTH = 3
#: Cycles' default pixel filter: Blackman-Harris, ``filter_width`` 1.5, which spans ±1.5 px (Cycles
#: doubles a Blackman-Harris width in ``filter_table``, scene/film.cpp). Lamina's width means the
#: same since this benchmark's edge regions found it spanning half that (up to 13 σ apart).
FILM_FILTER = {"type": "blackman-harris", "width": 1.5}      # Blender's default, both renderers


def _metal(name: str, alpha: float) -> dict:
    eta, k = metal_ior(name)
    return {"type": "conductor", "eta": [round(float(x), 6) for x in eta], "k": [round(float(x), 6) for x in k],
            "roughness": alpha}


def _scene(size, camera, materials, meshes, objects, lights=(), world=None, clamp: float = 0.0) -> dict:
    data = {"format": "lamina-scene", "version": 1,
            "film": {"width": size, "height": size, "filter": dict(FILM_FILTER)},
            "camera": camera, "render": {"max_bounces": MAX_BOUNCES, "rr_depth": RR_DEPTH, "clamp": clamp, "seed": 1},
            "materials": materials, "meshes": meshes, "objects": list(objects), "lights": list(lights)}
    if world is not None:
        data["world"] = world
    return data


# --------------------------------------------------------------------------- the scenes

def cornell(size: int) -> dict:
    """The issue's Cornell box: rough gold (GGX α 0.2) and rough glass (α 0.1) spheres, one area
    light that the camera sees (so 'the light seen directly' is a region of the agreement check)."""
    meshes = {
        "floor": _quad([-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]),
        "ceiling": _quad([-1, -1, 2], [-1, 1, 2], [1, 1, 2], [1, -1, 2]),
        "back": _quad([-1, 1, 0], [1, 1, 0], [1, 1, 2], [-1, 1, 2]),
        "left": _quad([-1, -1, 0], [-1, 1, 0], [-1, 1, 2], [-1, -1, 2]),
        "right": _quad([1, -1, 0], [1, -1, 2], [1, 1, 2], [1, 1, 0]),
        "sphere": {"shape": "sphere", "radius": 0.4, "segments": 96},
    }
    materials = {
        "white": {"type": "diffuse", "color": [0.73, 0.73, 0.73]},
        "red": {"type": "diffuse", "color": [0.63, 0.065, 0.05]},
        "green": {"type": "diffuse", "color": [0.14, 0.45, 0.091]},
        "gold": _metal("Au", 0.2),
        "glass": {"type": "dielectric", "ior": 1.5, "roughness": 0.1},
    }
    objects = [
        {"name": "floor", "mesh": "floor", "materials": ["white"]},
        {"name": "ceiling", "mesh": "ceiling", "materials": ["white"]},
        {"name": "back wall", "mesh": "back", "materials": ["white"]},
        {"name": "red wall", "mesh": "left", "materials": ["red"]},
        {"name": "green wall", "mesh": "right", "materials": ["green"]},
        {"name": "gold sphere", "mesh": "sphere", "to_world": _m(-0.45, 0.3, 0.4), "materials": ["gold"]},
        {"name": "glass sphere", "mesh": "sphere", "to_world": _m(0.45, -0.2, 0.4), "materials": ["glass"]},
    ]
    # 0.6 m square light 2 cm below the ceiling, facing down (area lights emit along local −Z),
    # visible to camera rays in both renderers.
    lights = [{"type": "area", "to_world": _m(0, 0, 1.98), "shape": "square", "size": 0.6,
               "power": 60.0, "color": [1.0, 0.85, 0.7], "visible_camera": True}]
    camera = {"type": "perspective",
              "to_world": [[1, 0, 0, 0], [0, 0, -1, -3.8], [0, 1, 0, 1], [0, 0, 0, 1]],
              "frame": [[0.3, 0.3, -1], [0.3, -0.3, -1], [-0.3, -0.3, -1], [-0.3, 0.3, -1]]}
    return _scene(size, camera, materials, meshes, objects, lights)


def _strips(names: list[str], width: float = 0.6, length: float = 1.6) -> tuple[dict, list]:
    """Adjacent rectangles in the plane z = 0 along x (one object and one material each)."""
    meshes = {"strip": {"shape": "rectangle", "size": [width, length]}}
    x0 = -width * (len(names) - 1) / 2
    objects = [{"name": f"{n} strip", "mesh": "strip", "to_world": _m(x0 + i * width, 0, 0), "materials": [n]}
               for i, n in enumerate(names)]
    return meshes, objects


def furnace(size: int) -> dict:
    """White furnace: an albedo-1 Lambert strip, a rough-gold strip and an F = 1 conductor strip
    (eta 0, k 1: total reflection at every angle) under a constant white world. The Lambert strip
    must come out exactly as bright as the world; the conductors lose what single-scattering GGX
    loses (the same in both renderers, since both use the height-correlated Smith term)."""
    materials = {"lambert": {"type": "diffuse", "color": [1.0, 1.0, 1.0]},
                 "gold": _metal("Au", 0.2),
                 "mirror": {"type": "conductor", "eta": [0.0, 0.0, 0.0], "k": [1.0, 1.0, 1.0], "roughness": 0.3}}
    meshes, objects = _strips(["lambert", "gold", "mirror"])
    camera = perspective((0, -2.6, 1.9), (0, 0, 0), 45.0, size, size)
    world = {"type": "constant", "color": [1.0, 1.0, 1.0], "strength": 1.0}
    return _scene(size, camera, materials, meshes, objects, world=world)


def grazing(size: int) -> dict:
    """Lambert, gold and rough-dielectric strips lit by a small square emitter at 82° incidence
    (8° above the plane, 3 m from its centre, facing it); black world. The camera looks from the
    other side, into the forward-scattered glossy lobes."""
    materials = {"lambert": {"type": "diffuse", "color": [0.8, 0.8, 0.8]},
                 "gold": _metal("Au", 0.2),
                 "dielectric": {"type": "dielectric", "ior": 1.5, "roughness": 0.1}}
    meshes, objects = _strips(["lambert", "gold", "dielectric"])
    theta = math.radians(82.0)
    d = 3.0
    pos = (0.0, d * math.sin(theta), d * math.cos(theta))
    # The light's local −Z must point from the light to the strips' centre: local +Z = pos / |pos|.
    z = [p / d for p in pos]
    x = [1.0, 0.0, 0.0]
    y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]]
    to_world = [[x[0], y[0], z[0], pos[0]], [x[1], y[1], z[1], pos[1]], [x[2], y[2], z[2], pos[2]], [0, 0, 0, 1]]
    lights = [{"type": "area", "to_world": to_world, "shape": "square", "size": 0.15, "power": 400.0,
               "color": [1.0, 1.0, 1.0]}]
    camera = perspective((0, -2.4, 1.5), (0, 0.1, 0), 48.0, size, size)
    return _scene(size, camera, materials, meshes, objects, lights)


def ies_room(size: int) -> dict:
    """An open corner lit by an asymmetric IES luminaire (a point light with the RAB profile of
    tests/data/ies) and a directional area light. Blender's directional area light is ``spread``
    (Cycles' soft-box falloff, which Lamina implements exactly): Lamina's own cutoff/beam shape has
    no Cycles counterpart, so it is not used here."""
    meshes = {
        "floor": _quad([-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]),
        "back": _quad([-2, 1.5, 0], [2, 1.5, 0], [2, 1.5, 2.5], [-2, 1.5, 2.5]),
        "right": _quad([1.8, -2, 0], [1.8, -2, 2.5], [1.8, 2, 2.5], [1.8, 2, 0]),
        "sphere": {"shape": "sphere", "radius": 0.45, "segments": 96},
        "box": {"shape": "cube", "size": 0.6},
    }
    materials = {"wall": {"type": "diffuse", "color": [0.7, 0.7, 0.7]},
                 "floor": {"type": "diffuse", "color": [0.55, 0.5, 0.45]},
                 "metal": _metal("Al", 0.15),
                 "box": {"type": "diffuse", "color": [0.2, 0.35, 0.7]}}
    objects = [{"name": "floor", "mesh": "floor", "materials": ["floor"]},
               {"name": "back wall", "mesh": "back", "materials": ["wall"]},
               {"name": "right wall", "mesh": "right", "materials": ["wall"]},
               {"name": "aluminium sphere", "mesh": "sphere", "to_world": _m(0.5, 0.4, 0.45), "materials": ["metal"]},
               {"name": "box", "mesh": "box", "to_world": _m(-0.6, 0.6, 0.3), "materials": ["box"]}]
    # Area light on the left facing +X (its local −Z is world +X), spread 60°.
    dv = [[0, 0, -1, -1.9], [1, 0, 0, 0.3], [0, -1, 0, 1.0], [0, 0, 0, 1]]
    lights = [{"type": "point", "to_world": _m(0.2, 0.3, 2.4), "power": 1.0, "color": [1, 0.95, 0.85],
               "radius": 0.0, "ies": {"file": str(IES_DIR / "rab_asym360_45deg_lm02.ies")}},
              {"type": "area", "to_world": dv, "shape": "rectangle", "size": 1.0, "size_y": 0.6,
               "power": 60.0, "color": [0.8, 0.9, 1.0], "spread": 60.0}]
    camera = perspective((0, -4.2, 1.4), (0, 0.5, 0.6), 50.0, size, size)
    return _scene(size, camera, materials, meshes, objects, lights)


#: The coat of the layered scene: a clear dielectric (index 1.5, GGX α 0.02) over a red Lambertian
#: body with an empty layer between them (Lamina's glossy-plastic stack, rougher coat).
COAT = {"type": "layered",
        "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.02},
                       {"type": "diffuse", "color": [0.6, 0.04, 0.03]}],
        "media": [{"thickness": 1.0, "sigma_t": 0.0, "albedo": [1, 1, 1]}]}


def layered(size: int) -> dict:
    """Two coated spheres on a grey floor in front of a wall, under an area light and a dim
    constant world. Lamina renders its two-interface stack (a position-free random walk between
    the coat and the body); Cycles renders the Principled BSDF with Coat (to_cycles.py): different
    materials, so this scene compares time to equal *own* relative noise, not images."""
    meshes = {"floor": _quad([-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]),
              "wall": _quad([-3, 1.2, 0], [3, 1.2, 0], [3, 1.2, 3], [-3, 1.2, 3]),
              "sphere": {"shape": "sphere", "radius": 0.5, "segments": 96}}
    materials = {"grey": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}, "coat": COAT}
    objects = [{"name": "floor", "mesh": "floor", "materials": ["grey"]},
               {"name": "wall", "mesh": "wall", "materials": ["grey"]},
               {"name": "coated sphere L", "mesh": "sphere", "to_world": _m(-0.6, 0.2, 0.5), "materials": ["coat"]},
               {"name": "coated sphere R", "mesh": "sphere", "to_world": _m(0.6, -0.1, 0.5), "materials": ["coat"]}]
    lights = [{"type": "area", "to_world": [[1, 0, 0, -0.8], [0, 0.8, -0.6, -1.6], [0, 0.6, 0.8, 2.6], [0, 0, 0, 1]],
               "shape": "square", "size": 0.8, "power": 120.0, "color": [1, 1, 1]}]
    world = {"type": "constant", "color": [0.6, 0.7, 0.9], "strength": 0.25}
    camera = perspective((0, -3.6, 1.3), (0, 0.2, 0.45), 42.0, size, size)
    return _scene(size, camera, materials, meshes, objects, lights, world=world)


# --------------------------------------------------------------------------- Principled BSDF scenes

@lru_cache(maxsize=1)
def _principled_export():
    # The add-on's own module, loaded once without bpy (the add-on package imports bpy).
    return principled_module()


def principled(p: dict) -> dict:
    """The Lamina material the Blender add-on exports for Principled BSDF settings ``p``."""
    return _principled_export().principled_material(p)[0]


def _sun_and_world() -> tuple[list, dict]:
    """A sun (5°, 3 W/m²) from the front left, behind the camera (so neither renderer's camera
    sees its disk), and a constant pale-blue world: the daylight set-up of benchmarks/everyday.py."""
    to_sun = (-0.45, -0.55, 0.70)
    # look_at's local −Z points from its eye to the target: from the sun's side to the origin,
    # the direction the sun shines.
    sun = {"type": "sun", "strength": 3.0, "angle": 5.0, "color": [1.0, 0.97, 0.92],
           "to_world": look_at(to_sun, (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))}
    world = {"type": "constant", "color": [0.3, 0.35, 0.42], "strength": 1.0}
    return [sun], world


#: The everyday scene's materials as an artist sets them in Blender's Principled BSDF: the keys of
#: ``principled_material`` (addon/export/principled.py); every other input at Blender's default.
EVERYDAY = {
    "ground": {"base_color": (0.45, 0.45, 0.45), "roughness": 0.5},        # default grey, darker
    "wall": {"base_color": (0.6, 0.45, 0.32), "roughness": 0.5},
    "red plastic": {"base_color": (0.8, 0.05, 0.04), "roughness": 0.3},
    "gold": {"base_color": (0.9, 0.7, 0.3), "metallic": 1.0, "roughness": 0.3},
    "coated blue": {"base_color": (0.05, 0.2, 0.6), "roughness": 0.5, "coat_weight": 1.0},
    "coated copper": {"base_color": (0.9, 0.55, 0.45), "metallic": 1.0, "roughness": 0.4, "coat_weight": 1.0},
    "glass": {"base_color": (1.0, 1.0, 1.0), "transmission": 1.0, "roughness": 0.0},
}


SPHERE_R = 0.35
#: Cycles' default indirect clamp, as artists render: the sunlit glass and smooth coats of these two
#: scenes make caustic fireflies (light through the glass onto the ground, found only by BSDF
#: sampling the small sun) that left the unclamped errors of both renderers dominated by single
#: paths, non-monotonic in the samples (error-vs-samples slopes −0.15 and −0.05).
ARTIST_CLAMP = 10.0


def _five_spheres(materials: list) -> list:
    """Three spheres in front, two behind in the gaps (each material its own sphere)."""
    places = [(-0.9, -0.3), (0.0, -0.3), (0.9, -0.3), (-0.45, 0.55), (0.45, 0.55)]
    return [{"name": f"{m} sphere", "mesh": "sphere", "to_world": _m(x, y, SPHERE_R), "materials": [m]}
            for m, (x, y) in zip(materials, places)]


def _five_spheres_camera(size: int) -> dict:
    # High enough that the back row shows above the front row.
    return perspective((0, -3.9, 2.1), (0, 0.15, 0.3), 40.0, size, size)


def everyday(size: int) -> dict:
    """Blender's default material as an artist uses it: a Principled ground and wall, and
    Principled spheres (plastic, gold, coat over a blue base, coat over copper, clear glass) under
    a sun and a constant world. Lamina renders what its add-on exports for each Principled
    setting, Cycles the Principled BSDF itself: the same .blend in both renderers."""
    meshes = {"ground": _quad([-4, -4, 0], [4, -4, 0], [4, 1.6, 0], [-4, 1.6, 0]),
              "wall": _quad([-4, 1.6, 0], [4, 1.6, 0], [4, 1.6, 3], [-4, 1.6, 3]),
              "sphere": {"shape": "sphere", "radius": SPHERE_R, "segments": 96}}
    materials = {name: principled(p) for name, p in EVERYDAY.items()}
    objects = [{"name": "ground", "mesh": "ground", "materials": ["ground"]},
               {"name": "wall", "mesh": "wall", "materials": ["wall"]}]
    objects += _five_spheres(["red plastic", "glass", "gold", "coated blue", "coated copper"])
    lights, world = _sun_and_world()
    return _scene(size, _five_spheres_camera(size), materials, meshes, objects, lights, world=world,
                  clamp=ARTIST_CLAMP)


#: The presets on the spheres of the presets scene (untextured, isotropic).
PRESETS = ["plastic-red-glossy", "car-paint-red", "ceramic-glaze-white", "guo-coated-copper",
           "anodized-aluminium-blue"]

#: Cycles' stand-ins for the presets: Principled settings by hand, with the free colour (base
#: colour or coat tint) chosen so that Cycles' albedo under uniform light (principled.py's tables,
#: ``info["target"]``) equals the preset's own, measured with ``python -m backend bsdf albedo
#: PRESET --theta T --samples 40000`` at θ = 20.7°, 37.8°, 52.2°, 69.3° (cos²θ at the midpoints of
#: four equal bins, so their mean is the cosine-weighted albedo). Roughness sliders are √α of the
#: preset's interfaces. They look alike, they are not the same materials.
PRESET_PRINCIPLED = {
    # Smooth dielectric over a red Lambertian body: exactly Principled's specular-over-diffuse
    # shape. The body's weak green and blue (0.04, 0.03) are lost to internal reflection under
    # the smooth interface: the stack reflects no more than Cycles' specular layer alone there.
    "plastic-red-glossy": {"base_color": (0.365, 0.0, 0.0), "roughness": 0.045},
    # Clear coat over a red scattering basecoat (optical depth 3) over aluminium: a coat over a
    # diffuse red base with its own specular layer off (the basecoat has no interface of its own);
    # the aluminium's flop through the thin basecoat at normal incidence is not reproduced.
    "car-paint-red": {"base_color": (0.12, 0.0, 0.0), "roughness": 0.5, "specular_ior_level": 0.0,
                      "coat_weight": 1.0, "coat_roughness": 0.071},
    # Smooth glaze over a dense, nearly white scattering layer over a clay body: specular over a
    # diffuse base; the layer's milky depth is approximated as a diffuse colour (no subsurface:
    # the slab's thickness is dimensionless, so there is no lateral scale to give Cycles).
    "ceramic-glaze-white": {"base_color": (0.422, 0.373, 0.281), "roughness": 0.055},
    # Rough coat (Beckmann α 0.05) over rough copper with a blue forward-scattering medium between:
    # a coated metal (GGX, √α) whose base colour carries the medium's blue haze and absorption.
    "guo-coated-copper": {"base_color": (0.12, 0.105, 0.214), "metallic": 1.0, "roughness": 0.224,
                          "coat_weight": 1.0, "coat_roughness": 0.224},
    # Clear oxide with a purely absorbing blue dye over aluminium: an aluminium metal under a coat
    # whose tint is the dye (Cycles' coat tint deepens at grazing angles like a path through dye);
    # red stays 0.0866 against the preset's 0.080 (the coat's own reflection).
    "anodized-aluminium-blue": {"base_color": (0.912, 0.914, 0.92), "metallic": 1.0, "roughness": 0.387,
                                "coat_weight": 1.0, "coat_roughness": 0.224, "coat_tint": (0.01, 0.06, 0.42)},
}


def presets(size: int) -> dict:
    """Layered presets on spheres over a Principled ground, under the sun and world of
    "everyday". Lamina renders the presets (named in the scene as a user would name them);
    Cycles renders ``PRESET_PRINCIPLED``: different materials, so this scene compares time to
    equal *own* relative noise."""
    # Ground to 40 m: the camera's highest rays meet it at about 30 m, so the world is seen only
    # in reflections. Seen directly it is noise-free in both renderers, and the agreement table
    # would list float rounding as infinitely many standard errors.
    meshes = {"ground": _quad([-40, -40, 0], [40, -40, 0], [40, 40, 0], [-40, 40, 0]),
              "sphere": {"shape": "sphere", "radius": SPHERE_R, "segments": 96}}
    materials = {"ground": principled(EVERYDAY["ground"]), **{p: p for p in PRESETS}}
    objects = [{"name": "ground", "mesh": "ground", "materials": ["ground"]}] + _five_spheres(PRESETS)
    lights, world = _sun_and_world()
    return _scene(size, _five_spheres_camera(size), materials, meshes, objects, lights, world=world,
                  clamp=ARTIST_CLAMP)


# --------------------------------------------------------------------------- registry

@dataclass
class PeerScene:
    name: str
    title: str
    build: object               # callable(size) -> scene dict
    size: int                   # pixels (square)
    spp: list                   # test sample counts, for both renderers
    ref_spp: int                # reference samples (both renderers; Cycles as REF_SPLIT renders)
    same_material: bool = True  # False: compare at equal own relative noise, no image agreement
    #: material name → Principled BSDF settings (``principled_material``'s keys): Cycles renders
    #: these names as a Principled BSDF node with the settings instead of converting the scene
    #: dict's material (convert.prepare's ``principled``).
    principled: dict = field(default_factory=dict)
    quick_size: int = 24
    quick_spp: list = field(default_factory=lambda: [1, 2, 4, 8])
    quick_ref_spp: int = 64


# The furnace and the grazing plane are cheap per sample (0.3–1.2 µs): their series go to 256 spp
# so that sampling, not the fixed start-up cost, dominates the largest renders and the marginal
# cost per sample is measurable; their references have 4096 spp to stay 16× the largest series.


def _pow2(a: int, b: int) -> list:
    return [1 << k for k in range(a, b + 1)]


PEER_SCENES = [
    PeerScene("cornell", "Cornell box: rough gold (α 0.2) and rough glass (α 0.1) spheres, visible area light",
              cornell, 96, _pow2(0, 6), 1024),
    PeerScene("furnace", "White furnace: albedo-1 Lambert, rough gold, F = 1 conductor (α 0.3) under a constant world",
              furnace, 96, _pow2(0, 8), 4096),
    PeerScene("grazing", "Lambert, gold and rough-dielectric strips under a small emitter at 82° incidence",
              grazing, 96, _pow2(0, 8), 4096),
    PeerScene("ies_room", "Room with an asymmetric IES point light and a directional (spread 60°) area light",
              ies_room, 96, _pow2(0, 6), 1024),
    PeerScene("layered", "Coated spheres: Lamina's 2-interface coat vs Cycles' Principled with Coat",
              layered, 80, _pow2(0, 5), 512, same_material=False),
    PeerScene("everyday", "Principled BSDF ground, wall and spheres (plastic, gold, coated, coated copper, glass) "
              "under a 5° sun and a constant world: the same .blend in both renderers",
              everyday, 96, _pow2(0, 6), 1024, principled=EVERYDAY),
    PeerScene("presets", "Layered presets (Lamina) vs hand-made Principled stand-ins (Cycles) on spheres over a "
              "Principled ground, sun and world", presets, 80, _pow2(0, 5), 512, same_material=False,
              principled={"ground": EVERYDAY["ground"], **PRESET_PRINCIPLED}),
]
