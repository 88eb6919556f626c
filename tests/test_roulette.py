"""Russian roulette (backend/kernels/integrator.py, ``_roulette``): survival min(1, √max throughput),
decided at a surface after the emission its ray found. It must not change the expected image:
a closed room with a visible area light (hit by BSDF sampling too), a rough-glass sphere (whose
radiance-mode BTDF lowers the throughput inside it) and a diffuse ball, rendered with roulette
from the first bounce on and without roulette, agrees region by region within K_SIGMA standard
errors (σ from each render's own per-pixel variance, fixed independent seeds)."""
import numpy as np

from render_util import region_means, render, scene

K_SIGMA = 4.0


def _room(rr_depth: int, seed: int, spp: int = 48, size: int = 32) -> dict:
    def quad(a, b, c, d):
        return {"positions": [a, b, c, d], "indices": [[0, 1, 2], [0, 2, 3]]}

    meshes = {   # a closed 2 m cube, faces towards the inside (diffuse is two-sided anyway)
        "floor": quad([-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]),
        "ceiling": quad([-1, -1, 2], [-1, 1, 2], [1, 1, 2], [1, -1, 2]),
        "back": quad([-1, 1, 0], [1, 1, 0], [1, 1, 2], [-1, 1, 2]),
        "front": quad([-1, -1, 0], [-1, -1, 2], [1, -1, 2], [1, -1, 0]),
        "left": quad([-1, -1, 0], [-1, 1, 0], [-1, 1, 2], [-1, -1, 2]),
        "right": quad([1, -1, 0], [1, -1, 2], [1, 1, 2], [1, 1, 0]),
        "ball": {"shape": "sphere", "radius": 0.35, "segments": 32},
    }
    materials = {"white": {"type": "diffuse", "color": [0.8, 0.8, 0.8]},
                 "red": {"type": "diffuse", "color": [0.7, 0.2, 0.1]},
                 "glass": {"type": "dielectric", "ior": 1.5, "roughness": 0.1}}
    objects = [{"mesh": k, "materials": ["red" if k == "left" else "white"]}
               for k in ("floor", "ceiling", "back", "front", "left", "right")]
    objects += [{"mesh": "ball", "to_world": [[1, 0, 0, 0.4], [0, 1, 0, 0.2], [0, 0, 1, 0.4], [0, 0, 0, 1]],
                 "materials": ["glass"]},
                {"mesh": "ball", "to_world": [[1, 0, 0, -0.45], [0, 1, 0, 0.4], [0, 0, 1, 0.35], [0, 0, 0, 1]],
                 "materials": ["white"]}]
    light = {"type": "area", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1.98], [0, 0, 0, 1]],
             "shape": "square", "size": 0.5, "power": 20.0, "color": [1, 1, 1], "visible_camera": True}
    camera = {"type": "perspective",
              "to_world": [[1, 0, 0, 0], [0, 0, -1, -0.95], [0, 1, 0, 1], [0, 0, 0, 1]],
              "frame": [[0.6, 0.6, -1], [0.6, -0.6, -1], [-0.6, -0.6, -1], [-0.6, 0.6, -1]]}
    return scene(size, size, camera, materials, meshes, objects, lights=[light],
                 render={"spp": spp, "max_bounces": 8, "rr_depth": rr_depth, "seed": seed})


def test_roulette_from_the_first_bounce_leaves_the_expected_image_unchanged():
    rr = render(_room(rr_depth=1, seed=11))
    full = render(_room(rr_depth=64, seed=12))
    a, va = rr.film.combined(), rr.film.variance_of_mean()
    b, vb = full.film.combined(), full.film.variance_of_mean()
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))
    mask = np.ones(a.shape[:2], bool)
    worst, power = 0.0, 0.0
    for blocks in (1, 4):          # the whole image (most sensitive), then 4 × 4 regions
        for (_, _, ma, sa, _), (_, _, mb, sb, _) in zip(region_means(a, va, mask, blocks),
                                                        region_means(b, vb, mask, blocks)):
            se = np.sqrt(sa ** 2 + sb ** 2)
            worst = max(worst, float((np.abs(ma - mb) / se).max()))
            power = max(power, float((0.02 * np.abs(mb) / se).max()))
    assert worst <= K_SIGMA, worst
    # The test has power: a 2 % darker image would fail it.
    assert power > K_SIGMA, power
    # Roulette did end paths: fewer rays were traced.
    assert rr.stats["rays"] < 0.9 * full.stats["rays"], (rr.stats["rays"], full.stats["rays"])
