"""Mesh lights with textured, two-sided emission against numerical quadrature of the irradiance."""
import numpy as np
import OpenImageIO as oiio

from render_util import look_down_ortho, region_means, scene

K_SIGMA = 4.0


def write_exr(path, pixels):
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(w, h, c, oiio.FLOAT))
    out.write_image(np.ascontiguousarray(pixels, dtype=np.float32))
    out.close()


def bilinear_repeat(tex, u, v):
    """Independent bilinear lookup (texel centres at (i + ½)/w, v up, repeat)."""
    h, w = tex.shape[:2]
    x = u * w - 0.5
    y = (1 - v) * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    def at(yy, xx):
        return tex[yy % h, xx % w]
    return ((at(y0, x0) * (1 - fx)[..., None] + at(y0, x0 + 1) * fx[..., None]) * (1 - fy)[..., None]
            + (at(y0 + 1, x0) * (1 - fx)[..., None] + at(y0 + 1, x0 + 1) * fx[..., None]) * fy[..., None])


def test_textured_two_sided_emitter_irradiance(tmp_path):
    tex = np.array([[[8.0, 1.0, 0.5], [0.5, 2.0, 6.0]], [[1.0, 6.0, 1.0], [4.0, 4.0, 4.0]]], np.float32)
    write_exr(tmp_path / "emit.exr", tex)
    # A 1 m × 1 m emitter standing vertically in the plane x = 0 (z from 0.25 to 1.25, y in
    # [-0.5, 0.5]); its winding normal faces −X, the lit floor is at x > 0: the *back* face lights it.
    corners = [[0, -0.5, 0.25], [0, -0.5, 1.25], [0, 0.5, 1.25], [0, 0.5, 0.25]]
    uvs = [[0, 0], [0, 1], [1, 1], [1, 0]]
    emitter = {"positions": corners, "indices": [[0, 1, 2], [0, 2, 3]], "uvs": uvs}
    rho = 0.5
    half = 1.0
    data = scene(24, 24, look_down_ortho(half, height=5.0),
                 {"floor": {"type": "diffuse", "color": rho},
                  "glow": {"type": "emission", "color": {"texture": "emit.exr"}, "strength": 1.0}},
                 {"floor": {"shape": "rectangle", "size": [2 * half, 2 * half]}, "emitter": emitter},
                 [{"mesh": "floor", "to_world": [[1, 0, 0, 1.2], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
                   "materials": ["floor"]},
                  {"mesh": "emitter", "materials": ["glow"]}],
                 render={"spp": 256, "max_bounces": 0, "seed": 9},
                 film_filter={"type": "box", "width": 1.0})
    # The camera looks at x ∈ [0.2, 2.2] so the emitter (at x = 0, seen edge-on) is out of view.
    data["camera"]["to_world"][0][3] = 1.2
    from backend.render import Renderer, RenderOptions
    from backend.scene.loader import load_scene_data
    sc = load_scene_data(data, str(tmp_path / "scene.json"), tmp_path)
    result = Renderer(sc, None, RenderOptions(workers=1)).run()
    img = result.film.combined()
    var = result.film.variance_of_mean()

    # Quadrature: E(x) = ∫ L(y) cosθx cosθy / r² dA over the emitter (midpoint rule, 160²).
    k = 160
    s = (np.arange(k) + 0.5) / k
    U, V = np.meshgrid(s, s, indexing="ij")
    ys = -0.5 + U
    zs = 0.25 + V
    L = bilinear_repeat(tex.astype(np.float64), U, V).reshape(-1, 3)
    Y = ys.ravel()
    Z = zs.ravel()
    dA = 1.0 / (k * k)

    def radiance_at(px, py):
        dx, dy, dz = px, py - Y, -Z
        r2 = dx * dx + dy * dy + dz * dz
        cos_floor = Z / np.sqrt(r2)          # floor normal +Z, towards the emitter point
        cos_emit = px / np.sqrt(r2)          # emitter normal ±X (two-sided), towards the floor point
        e = (L * (cos_floor * cos_emit / r2 * dA)[:, None]).sum(axis=0)
        return rho / np.pi * e

    size = 24
    pix = 2 * half / size
    offsets = (np.arange(3) - 1) * pix / 3          # 3×3 points per pixel: the box-filter footprint
    ones = np.ones(img.shape[:2], bool)
    for by, bx, _, _, (yy, xx) in region_means(img, var, ones, 3):
        rows = range(yy.start, yy.stop, 2)           # every other pixel keeps the quadrature cheap
        cols = range(xx.start, xx.stop, 2)
        ref = np.mean([radiance_at(1.2 - half + (j + 0.5) * pix + ox, half - (i + 0.5) * pix + oy)
                       for i in rows for j in cols for ox in offsets for oy in offsets], axis=0)
        values = np.array([img[i, j] for i in rows for j in cols])
        variances = np.array([var[i, j] for i in rows for j in cols])
        mean = values.mean(axis=0)
        se = np.sqrt(variances.sum(axis=0)) / len(values)
        assert np.all(np.abs(mean - ref) <= K_SIGMA * se + 1e-3 * ref), (by, bx, mean, ref, se)
