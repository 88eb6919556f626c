"""Benchmark scenes built in code (dicts in the scene format, docs/scene-format.md).

Scenes are plain data: each builder returns a scene dict, and ``BENCH_SCENES`` lists what the
report renders (name, builder, sizes, sample counts). A scene that needs a material or light type
which has not landed yet simply fails to load; the report says so and carries on.

Layered stacks follow the paper's validation scenes (Guo et al. 2018, Fig. 2 and the supplement): slab
thickness 1 so ``sigma_t`` is the optical depth at normal incidence; Beckmann microfacets with the
separable (Smith G1·G1) masking of the reference implementation; conductor Cu.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
IES_DIR = REPO / "tests" / "data" / "ies"


# --------------------------------------------------------------------------- small helpers

def _m(tx=0.0, ty=0.0, tz=0.0, s=1.0):
    return [[s, 0, 0, tx], [0, s, 0, ty], [0, 0, s, tz], [0, 0, 0, 1]]


def _quad(p0, p1, p2, p3):
    """Inline mesh of one quad (counter-clockwise seen from the front)."""
    return {"positions": [p0, p1, p2, p3], "indices": [[0, 1, 2], [0, 2, 3]]}


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> list:
    """Camera ``to_world``: the camera looks down its local −Z, +Y is up (Blender's convention)."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    z = eye - target
    z /= np.linalg.norm(z)
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, eye
    return m.tolist()


def perspective(eye, target, fov_deg: float, width: int, height: int, up=(0.0, 0.0, 1.0)) -> dict:
    """A perspective camera whose horizontal field of view is ``fov_deg`` (Mitsuba's default axis)."""
    hw = math.tan(math.radians(fov_deg) / 2)
    hh = hw * height / width
    return {"type": "perspective", "to_world": look_at(eye, target, up),
            "frame": [[hw, hh, -1], [hw, -hh, -1], [-hw, -hh, -1], [-hw, hh, -1]]}


def _scene(width, height, camera, materials, meshes, objects, lights=(), world=None, render=None) -> dict:
    data = {"format": "lamina-scene", "version": 1, "film": {"width": width, "height": height},
            "camera": camera, "render": dict(render or {}), "materials": materials, "meshes": meshes,
            "objects": list(objects), "lights": list(lights)}
    if world is not None:
        data["world"] = world
    return data


def sphere_light_power(radiance: float, radius: float) -> float:
    """Cycles' point light of radius r has radiance P/(4π² r²) (docs/lights.md, Point lights): P for a given L."""
    return radiance * 4.0 * math.pi ** 2 * radius ** 2


# --------------------------------------------------------------------------- layered stacks

def _rough(kind: str, alpha, alpha_v=None, **extra) -> dict:
    d = {"type": kind, "roughness": alpha, "distribution": "beckmann", "masking": "separable", **extra}
    if alpha_v is not None:
        d["roughness_v"] = alpha_v
    return d


def validation_stack(which: int) -> dict:
    """The paper's validation stacks (Guo et al. 2018): 1 = Fig. 2 top, 2 and 3 = supplement,
    4 = Fig. 2 bottom (three interfaces, two microflake media)."""
    if which in (1, 2, 3):
        sigma_t, g, cu_alpha = {1: (1.0, 0.5, 0.05), 2: (2.0, 0.9, 0.01), 3: (5.0, 0.95, 0.01)}[which]
        return {"type": "layered",
                "interfaces": [_rough("dielectric", 0.05, ior=1.5), _rough("conductor", cu_alpha, metal="Cu")],
                "media": [{"thickness": 1.0, "sigma_t": sigma_t, "albedo": [0.5, 0.7, 0.95],
                           "phase": {"type": "hg", "g": g}}]}
    if which == 4:
        return {"type": "layered",
                "interfaces": [_rough("dielectric", 0.05, 0.25, ior=1.5), _rough("dielectric", 0.01, ior=1.2),
                               _rough("conductor", 0.05, metal="Cu")],
                "media": [{"thickness": 1.0, "sigma_t": 0.5, "albedo": [0.5, 0.7, 0.95],
                           "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, 0.5, 0.0]}},
                          {"thickness": 1.0, "sigma_t": 0.5, "albedo": [0.5, 0.95, 0.5],
                           "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, -0.5, 0.0]}}]}
    raise ValueError(f"no validation stack {which}")


# --------------------------------------------------------------------------- scenes

def cornell_box(width=256, height=256, spp=16, max_bounces=6, area_light=True) -> dict:
    """A Cornell-like room 2 m wide (x ∈ [-1, 1], y ∈ [-1, 1], z ∈ [0, 2]), open towards −Y where the
    camera stands, with a rough conductor sphere and a dielectric sphere and a ceiling light."""
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
        "gold": {"type": "conductor", "metal": "Au", "roughness": 0.1},
        "glass": {"type": "dielectric", "ior": 1.5, "roughness": 0.0},
    }
    objects = [
        {"name": "floor", "mesh": "floor", "materials": ["white"]},
        {"name": "ceiling", "mesh": "ceiling", "materials": ["white"]},
        {"name": "back", "mesh": "back", "materials": ["white"]},
        {"name": "left", "mesh": "left", "materials": ["red"]},
        {"name": "right", "mesh": "right", "materials": ["green"]},
        {"name": "metal ball", "mesh": "sphere", "to_world": _m(-0.45, 0.3, 0.4), "materials": ["gold"]},
        {"name": "glass ball", "mesh": "sphere", "to_world": _m(0.45, -0.2, 0.4), "materials": ["glass"]},
    ]
    lights = []
    if area_light:
        # A 0.5 m square light just below the ceiling, facing down (area lights emit along local −Z).
        lights.append({"type": "area", "to_world": _m(0, 0, 1.98), "shape": "square", "size": 0.5,
                       "power": 60.0, "color": [1, 0.85, 0.7]})
    camera = {"type": "perspective",
              "to_world": [[1, 0, 0, 0], [0, 0, -1, -3.8], [0, 1, 0, 1], [0, 0, 0, 1]],
              "frame": [[0.3, 0.3, -1], [0.3, -0.3, -1], [-0.3, -0.3, -1], [-0.3, 0.3, -1]]}
    return _scene(width, height, camera, materials, meshes, objects, lights,
                  render={"spp": spp, "max_bounces": max_bounces, "seed": 1})


def validation_plane(which: int, size: int = 64, max_bounces: int = 2) -> dict:
    """Fig. 2 of the paper (Guo et al. 2018): a 400×400 plane at z = 0 seen from (0, −400, 400) with a
    15° field of view, lit by a sphere light of radius 10 and radiance 50 at (0, 100, 100) (on
    the mirror side). Nothing else: a path that leaves the plane escapes, so two bounces suffice."""
    camera = perspective((0, -400, 400), (0, 0, 0), 15.0, size, size)
    light = {"type": "point", "to_world": _m(0, 100, 100), "radius": 10.0,
             "power": sphere_light_power(50.0, 10.0), "color": [1, 1, 1]}
    return _scene(size, size, camera, {"stack": validation_stack(which)},
                  {"plane": {"shape": "rectangle", "size": [400, 400]}},
                  [{"name": "plane", "mesh": "plane", "materials": ["stack"]}], [light],
                  render={"max_bounces": max_bounces, "seed": 1})


def sky_map(path: Path, width: int = 256) -> Path:
    """Write a procedural equirectangular sky (float EXR, linear Rec.709): a horizon-to-zenith
    gradient, a darker ground and a small bright sun, so it has both smooth and peaked radiance.
    Rewritten only when its content changes."""
    h = width // 2
    v = (np.arange(h) + 0.5) / h                     # 0 = top row = zenith
    u = (np.arange(width) + 0.5) / width
    theta = v * np.pi                               # polar angle from +Z
    phi = u * 2 * np.pi
    elev = np.pi / 2 - theta[:, None] * np.ones((1, width))
    sky = np.where(elev[..., None] > 0,
                   np.array([0.25, 0.45, 0.9]) + (np.array([0.9, 0.9, 0.95]) - np.array([0.25, 0.45, 0.9]))
                   * np.exp(-elev[..., None] / 0.25),
                   np.array([0.18, 0.15, 0.12]))
    # Sun: 12° across at 35° elevation — wide enough that glass caustics of it are not single fireflies.
    sun_dir = np.array([math.cos(math.radians(35)) * math.cos(1.0), math.cos(math.radians(35)) * math.sin(1.0),
                        math.sin(math.radians(35))])
    d = np.stack([np.sin(theta)[:, None] * np.cos(phi)[None, :], np.sin(theta)[:, None] * np.sin(phi)[None, :],
                  np.cos(theta)[:, None] * np.ones((1, width))], axis=-1)
    sun = (d @ sun_dir) > math.cos(math.radians(6.0))
    sky = sky + sun[..., None] * np.array([30.0, 27.5, 24.0])
    pixels = sky.astype(np.float32)
    digest = hashlib.sha256(pixels.tobytes()).hexdigest()[:12]
    path = Path(path).with_name(f"{Path(path).stem}-{digest}.exr")
    if not path.exists():
        import OpenImageIO as oiio
        path.parent.mkdir(parents=True, exist_ok=True)
        out = oiio.ImageOutput.create(str(path))
        spec = oiio.ImageSpec(width, h, 3, oiio.FLOAT)
        out.open(str(path), spec)
        out.write_image(pixels)
        out.close()
    return path


def _sphere_row(materials: list[str], z: float = 0.5) -> tuple[dict, list]:
    meshes = {"sphere": {"shape": "sphere", "radius": 0.5, "segments": 96},
              "ground": {"shape": "rectangle", "size": [40, 40]}}
    xs = np.linspace(-1.2, 1.2, len(materials)) if len(materials) > 1 else [0.0]
    objects = [{"name": "ground", "mesh": "ground", "materials": ["ground"]}]
    objects += [{"name": f"sphere {i}", "mesh": "sphere", "to_world": _m(float(x), 0.0, z), "materials": [m]}
                for i, (x, m) in enumerate(zip(xs, materials))]
    return meshes, objects


def env_spheres(cache: Path, size: int = 96, max_bounces: int = 4) -> dict:
    """Three spheres with the 3-layer reference stack (Validation 4) on a grey ground under the
    procedural sky; the sky fills the upper part of the frame."""
    w, h = size, size // 2
    meshes, objects = _sphere_row(["stack", "stack", "stack"])
    materials = {"stack": validation_stack(4), "ground": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}}
    camera = perspective((0, -5, 1.0), (0, 0, 0.75), 45.0, w, h)
    world = {"type": "environment", "file": str(sky_map(cache / "sky.exr"))}
    return _scene(w, h, camera, materials, meshes, objects, world=world,
                  render={"max_bounces": max_bounces, "seed": 1})


def sky_spheres(cache: Path, size: int = 128, max_bounces: int = 6) -> dict:
    """Gold, glass and white spheres on a grey ground under the procedural sky (no layered
    materials). The upper half of the frame is sky: large easy regions for adaptive sampling."""
    w, h = size, size // 2
    meshes, objects = _sphere_row(["gold", "glass", "white"])
    materials = {"gold": {"type": "conductor", "metal": "Au", "roughness": 0.05},
                 "glass": {"type": "dielectric", "ior": 1.5, "roughness": 0.0},
                 "white": {"type": "diffuse", "color": [0.8, 0.8, 0.8]},
                 "ground": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}}
    camera = perspective((0, -5, 1.0), (0, 0, 0.75), 45.0, w, h)
    world = {"type": "environment", "file": str(sky_map(cache / "sky.exr"))}
    return _scene(w, h, camera, materials, meshes, objects, world=world,
                  render={"max_bounces": max_bounces, "seed": 1})


def ies_room(size: int = 128, max_bounces: int = 6) -> dict:
    """An open corner (floor, back and right wall) lit by an asymmetric IES luminaire (RAB, from
    tests/data/ies) from above and a directional area light (cutoff 45°, beam 20°) on the left,
    with a rough aluminium sphere and a diffuse box."""
    meshes = {
        "floor": _quad([-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]),
        "back": _quad([-2, 1.5, 0], [2, 1.5, 0], [2, 1.5, 2.5], [-2, 1.5, 2.5]),
        "right": _quad([1.8, -2, 0], [1.8, -2, 2.5], [1.8, 2, 2.5], [1.8, 2, 0]),
        "sphere": {"shape": "sphere", "radius": 0.45, "segments": 96},
        "box": {"shape": "cube", "size": 0.6},
    }
    materials = {"wall": {"type": "diffuse", "color": [0.7, 0.7, 0.7]},
                 "floor": {"type": "diffuse", "color": [0.55, 0.5, 0.45]},
                 "metal": {"type": "conductor", "metal": "Al", "roughness": 0.15},
                 "box": {"type": "diffuse", "color": [0.2, 0.35, 0.7]}}
    objects = [{"name": "floor", "mesh": "floor", "materials": ["floor"]},
               {"name": "back", "mesh": "back", "materials": ["wall"]},
               {"name": "right", "mesh": "right", "materials": ["wall"]},
               {"name": "sphere", "mesh": "sphere", "to_world": _m(0.5, 0.4, 0.45), "materials": ["metal"]},
               {"name": "box", "mesh": "box", "to_world": _m(-0.6, 0.6, 0.3), "materials": ["box"]}]
    # Area light on the left facing +X: its local −Z (emission side) is world +X.
    dv = [[0, 0, -1, -1.9], [1, 0, 0, 0.3], [0, -1, 0, 1.0], [0, 0, 0, 1]]
    lights = [{"type": "point", "to_world": _m(0.2, 0.3, 2.4), "power": 1.0, "color": [1, 0.95, 0.85],
               "ies": {"file": str(IES_DIR / "rab_asym360_45deg_lm02.ies")}},
              {"type": "area", "to_world": dv, "shape": "rectangle", "size": 1.0, "size_y": 0.6,
               "power": 60.0, "color": [0.8, 0.9, 1.0], "cutoff_angle": 45.0, "beam_width": 20.0}]
    camera = perspective((0, -4.2, 1.4), (0, 0.5, 0.6), 50.0, size, size)
    return _scene(size, size, camera, materials, meshes, objects, lights,
                  render={"max_bounces": max_bounces, "seed": 1})


# --------------------------------------------------------------------------- registry

@dataclass
class BenchScene:
    """One time-vs-error scene: how to build it at full and quick size and how far to sample."""

    name: str
    title: str
    build: object                # callable(size, cache_dir) -> scene dict
    size: int                    # full-run width in pixels
    spp: list                    # test sample counts (full run)
    ref_spp: int                 # reference sample count (full run)
    quick_size: int = 16
    quick_spp: list = field(default_factory=lambda: [1, 2, 4, 8])
    quick_ref_spp: int = 64
    layered: bool = False        # needs the layered material
    notes: str = ""


def _pow2(a: int, b: int) -> list:
    return [1 << k for k in range(a, b + 1)]


BENCH_SCENES = [
    BenchScene("cornell", "Cornell-like room: rough gold and smooth glass spheres, area light",
               lambda size, cache: cornell_box(size, size, 16, 6), 128, _pow2(0, 6), 1024),
    BenchScene("ies_room", "Open room: asymmetric IES light + directional area light (cutoff 45°, beam 20°)",
               lambda size, cache: ies_room(size), 128, _pow2(0, 6), 1024),
    BenchScene("sky_spheres", "Gold, glass, white spheres under a procedural sky (environment map)",
               lambda size, cache: sky_spheres(cache, size), 128, _pow2(0, 8), 4096),
    BenchScene("validation1", "Plane under a sphere light, Validation 1 (Fig. 2 top): dielectric / HG medium / Cu",
               lambda size, cache: validation_plane(1, size), 48, _pow2(1, 6), 512, layered=True),
    BenchScene("validation2", "Plane under a sphere light, Validation 2 (σt 2, g 0.9, Cu α 0.01)",
               lambda size, cache: validation_plane(2, size), 48, _pow2(1, 6), 512, layered=True),
    BenchScene("validation3", "Plane under a sphere light, Validation 3 (σt 5, g 0.95, Cu α 0.01)",
               lambda size, cache: validation_plane(3, size), 48, _pow2(1, 6), 512, layered=True),
    BenchScene("validation4", "Plane under a sphere light, Validation 4 (Fig. 2 bottom): 3 interfaces, 2 microflake media",
               lambda size, cache: validation_plane(4, size), 48, _pow2(1, 6), 512, layered=True),
    BenchScene("env_spheres", "Spheres with the 3-layer reference stack (Validation 4) under the sky",
               lambda size, cache: env_spheres(cache, size), 64, _pow2(1, 6), 512, layered=True),
]


def referenced_files(data) -> list[Path]:
    """Every ``file`` a scene dict refers to (for cache keys)."""
    out = []
    if isinstance(data, dict):
        for k, v in data.items():
            if k == "file" and isinstance(v, str):
                out.append(Path(v))
            else:
                out += referenced_files(v)
    elif isinstance(data, list):
        for v in data:
            out += referenced_files(v)
    return out
