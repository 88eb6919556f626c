"""Noise on everyday materials: the scenes of issue 36's table, and their relative noise.

Each scene is one object under a sun (angle 5°, 3 W/m²) and a constant world (0.3): Blender's
default Principled ground (base colour 0.4, roughness 0.5) as the add-on exports it, the same
ground as a Lambertian of the same albedo, a sphere with a clear coat over rough gold, and a
sphere with the three-interface stack of Guo et al.'s Fig. 2 (rough coat / HG medium / rough Cu).

The figure is the issue's: per-pixel standard deviation over ``seeds`` renders at ``spp`` samples,
divided by the mean, over the pixels the object covers: sqrt(mean over pixels of the per-pixel
variance of the luminance) / mean luminance; and, as "typical pixel", the median over those
pixels of each pixel's own standard deviation / mean (``noise_figures``).

    .venv/bin/python -m benchmarks.everyday [--spp 32] [--seeds 4] [--size 96] [--estimator bi]

``--estimator bi`` renders every layered material with the random walk (the reference);
``--converged N`` also renders an N-spp image per scene and compares the means.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from .scenes import _m, _scene, perspective

LUM = np.array([0.2126, 0.7152, 0.0722])


def principled_module():
    """addon/export/principled.py loaded on its own (the add-on package imports bpy)."""
    import importlib.util
    from .scenes import REPO
    spec = importlib.util.spec_from_file_location("lamina_principled", REPO / "addon" / "export" / "principled.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def principled(**p) -> dict:
    """The Lamina material the add-on exports for Principled settings ``p``."""
    return principled_module().principled_material(p)[0]


def coated_gold() -> dict:
    """A clear coat (GGX α 0.01, index 1.5) over rough gold (α 0.09): what Blender's Principled
    with Metallic 1, base colour gold, roughness 0.3 and Coat 1, coat roughness 0.1 looks like."""
    return {"type": "layered",
            "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.01},
                           {"type": "conductor", "metal": "Au", "roughness": 0.09}],
            "media": [{"thickness": 1.0, "sigma_t": 0.0}]}


def fig2_stack() -> dict:
    from .scenes import validation_stack
    return validation_stack(1)


def _lights():
    sun = {"type": "sun", "strength": 3.0, "angle": 5.0,
           "to_world": [[1, 0, 0, 0], [0, 0.819152, -0.573576, 0], [0, 0.573576, 0.819152, 0], [0, 0, 0, 1]]}
    return [sun], {"type": "constant", "color": [0.3, 0.3, 0.3], "strength": 1.0}


def ground_scene(material: dict, size: int) -> dict:
    meshes = {"ground": {"positions": [[-4, -4, 0], [4, -4, 0], [4, 4, 0], [-4, 4, 0]],
                         "indices": [[0, 1, 2], [0, 2, 3]]}}
    camera = perspective((0, -3.0, 1.6), (0, 0, 0), 40.0, size, size)
    lights, world = _lights()
    return _scene(size, size, camera, {"m": material}, meshes,
                  [{"name": "ground", "mesh": "ground", "materials": ["m"]}], lights, world,
                  render={"max_bounces": 6, "seed": 1})


def sphere_scene(material: dict, size: int) -> dict:
    meshes = {"sphere": {"shape": "sphere", "radius": 1.0, "segments": 128}}
    camera = perspective((0, -4.0, 0.0), (0, 0, 0), 32.0, size, size)
    lights, world = _lights()
    return _scene(size, size, camera, {"m": material}, meshes,
                  [{"name": "sphere", "mesh": "sphere", "to_world": _m(), "materials": ["m"]}], lights, world,
                  render={"max_bounces": 6, "seed": 1})


def scenes(size: int) -> dict:
    ground = principled(base_color=(0.4, 0.4, 0.4), roughness=0.5)
    info: dict = {}
    principled_module().principled_material({"base_color": (0.4, 0.4, 0.4), "roughness": 0.5}, info)
    lambert = {"type": "diffuse", "color": [float(x) for x in info["target"]]}
    return {"principled ground": ground_scene(ground, size),
            "lambertian ground": ground_scene(lambert, size),
            "coated gold sphere": sphere_scene(coated_gold(), size),
            "fig. 2 stack sphere": sphere_scene(fig2_stack(), size)}


def with_render(data: dict, **render) -> dict:
    data = json.loads(json.dumps(data))
    data["render"].update(render)
    return data


def with_estimator(data: dict, estimator: str | None) -> dict:
    if estimator:
        data = json.loads(json.dumps(data))
        data["render"]["layered"] = {"estimator": estimator}
    return data


def measure(data: dict, spp: int, seeds: int) -> dict:
    from .measure import render
    imgs = []
    cpu = 0.0
    for s in range(seeds):
        run = render(data, spp, seed=1000 + s)
        imgs.append(run.image[..., :3] @ LUM)
        cpu += run.cpu
    out = noise_figures(np.stack(imgs))
    out["cpu_per_render"] = cpu / seeds
    return out


def noise_figures(stack: np.ndarray) -> dict:
    """Noise of ``seeds`` renders of one scene (luminance, shape (seeds, h, w)), over the pixels
    the object covers: ``relative_noise`` the image-wide figure, sqrt(mean per-pixel variance) /
    mean (dominated by the brightest pixels: a highlight holding 1 % of the pixels may hold
    99.9 % of the variance), and ``typical_pixel_noise`` the median over pixels of each pixel's
    own standard deviation / its mean (what most of the object looks like)."""
    mean = stack.mean(axis=0)
    mask = mean > 1e-3 * mean.max()
    var = stack.var(axis=0, ddof=1)
    rel = math.sqrt(float(var[mask].mean())) / float(mean[mask].mean())
    typical = float(np.median(np.sqrt(var[mask]) / mean[mask]))
    return {"relative_noise": rel, "typical_pixel_noise": typical, "mean": float(mean[mask].mean()),
            "mask": mask}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.everyday", description=__doc__.split("\n\n")[0])
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--estimator", choices=("bi", "uni", "auto"), default=None)
    ap.add_argument("--converged", type=int, default=0, help="also render N spp and compare the means")
    ap.add_argument("--only", default=None, help="a substring of the scene names")
    args = ap.parse_args(argv)
    from .measure import render
    for name, data in scenes(args.size).items():
        if args.only and args.only not in name:
            continue
        t0 = time.perf_counter()
        r = measure(with_estimator(data, args.estimator), args.spp, args.seeds)
        line = (f"{name:22s} noise {100 * r['relative_noise']:6.2f} %   typical pixel "
                f"{100 * r['typical_pixel_noise']:6.2f} %   mean {r['mean']:.5f}   "
                f"cpu/render {r['cpu_per_render']:.2f} s")
        if args.converged:
            ref = render(with_estimator(data, "bi"), args.converged, seed=99)
            refl = ref.image[..., :3] @ LUM
            m = float(refl[r["mask"]].mean())
            line += f"   walk {args.converged} spp mean {m:.5f} ({100 * (r['mean'] / m - 1):+.2f} %)"
        print(line + f"   [{time.perf_counter() - t0:.0f} s]", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
