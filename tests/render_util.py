"""Helpers for end-to-end render tests: build scene dicts, render in-process, compare regions."""
from __future__ import annotations

import copy

import numpy as np

from backend.render import Renderer, RenderOptions
from backend.scene.loader import load_scene_data

IDENTITY = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


def look_down_ortho(half_size: float, height: float = 5.0) -> dict:
    """Orthographic camera above the origin looking down −Z, image +Y = world +Y."""
    h = half_size
    return {"type": "orthographic", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, height], [0, 0, 0, 1]],
            "frame": [[h, h, -1], [h, -h, -1], [-h, -h, -1], [-h, h, -1]]}


def front_perspective(distance: float = 5.0, half_width: float = 0.3, aspect: float = 1.0) -> dict:
    """Perspective camera on −Y looking towards +Y (at the origin)."""
    hw, hh = half_width, half_width / aspect
    return {"type": "perspective",
            "to_world": [[1, 0, 0, 0], [0, 0, -1, -distance], [0, 1, 0, 0], [0, 0, 0, 1]],
            "frame": [[hw, hh, -1], [hw, -hh, -1], [-hw, -hh, -1], [-hw, hh, -1]]}


def quad(centre, a, b) -> dict:
    """A mesh of one parallelogram: centre ± a ± b (two triangles, counter-clockwise seen from
    a × b)."""
    c, a, b = (np.asarray(v, dtype=float) for v in (centre, a, b))
    return {"positions": [list(c - a - b), list(c + a - b), list(c + a + b), list(c - a + b)],
            "indices": [[0, 1, 2], [0, 2, 3]]}


def scene(width, height, camera, materials, meshes, objects, lights=(), world=None, render=None,
          film_filter=None) -> dict:
    data = {"format": "lamina-scene", "version": 1,
            "film": {"width": width, "height": height},
            "camera": camera, "materials": materials, "meshes": meshes, "objects": list(objects),
            "lights": list(lights), "render": render or {}}
    if film_filter is not None:
        data["film"]["filter"] = film_filter
    if world is not None:
        data["world"] = world
    return data


def render(data: dict, workers: int = 1, **options):
    sc = load_scene_data(copy.deepcopy(data), "<test>")
    opts = RenderOptions(workers=workers, **options)
    opts.apply(sc)
    return Renderer(sc, (copy.deepcopy(data), "<test>", None), opts).run()


def _blocks(h: int, w: int, blocks: int):
    """(by, bx, rows, columns) of a blocks × blocks split of an h × w image."""
    for by in range(blocks):
        for bx in range(blocks):
            yield (by, bx, slice(by * h // blocks, (by + 1) * h // blocks),
                   slice(bx * w // blocks, (bx + 1) * w // blocks))


def region_z(a, b, blocks: int) -> np.ndarray:
    """|z| of the difference of two renders' means over blocks × blocks regions, per channel (σ
    from both renders' own per-pixel variance of the mean; pixels are independent)."""
    ia, ib = a.film.combined()[..., :3], b.film.combined()[..., :3]
    va, vb = a.film.variance_of_mean(), b.film.variance_of_mean()
    out = []
    for _, _, ys, xs in _blocks(*ia.shape[:2], blocks):
        diff = ia[ys, xs].mean(axis=(0, 1)) - ib[ys, xs].mean(axis=(0, 1))
        se = np.sqrt(va[ys, xs].sum(axis=(0, 1)) + vb[ys, xs].sum(axis=(0, 1))) / ia[ys, xs, 0].size
        assert np.all(se > 0), "a region without noise cannot be compared"
        out.append(np.abs(diff) / se)
    return np.array(out)


def region_means(image: np.ndarray, var_of_mean: np.ndarray, mask: np.ndarray, blocks: int):
    """Split the image into blocks×blocks regions; per region the mean over masked pixels and its
    standard error (pixels are independent, so variances of pixel means add)."""
    out = []
    for by, bx, ys, xs in _blocks(*image.shape[:2], blocks):
        m = mask[ys, xs]
        k = int(m.sum())
        if k < 4:
            continue
        mean = image[ys, xs][m].mean(axis=0)
        se = np.sqrt(var_of_mean[ys, xs][m].sum(axis=0)) / k
        out.append((by, bx, mean, se, (ys, xs)))
    return out


def assert_no_gain_in_white_furnace(material: dict, spp: int = 64) -> None:
    """``material`` on a closed sphere under a constant white world (24², 64 bounces, no
    roulette): no pixel above the world's radiance by more than 4σ (σ from the pixel's own
    sample variance), no NaN, and the sphere is not black."""
    data = scene(24, 24, look_down_ortho(1.2), {"m": material},
                 {"ball": {"shape": "sphere", "radius": 1.0, "segments": 48}},
                 [{"mesh": "ball", "materials": ["m"]}], world={"type": "constant", "color": [1, 1, 1]},
                 render={"spp": spp, "max_bounces": 64, "seed": 5, "rr_depth": 64})
    r = render(data)
    img = r.film.combined()[..., :3]
    se = np.sqrt(r.film.variance_of_mean())
    assert np.all(np.isfinite(img))
    assert np.all(img <= 1.0 + 4.0 * se + 1e-6), float((img - 1.0 - 4.0 * se).max())
    assert img[8:16, 8:16].mean() > 0.3
