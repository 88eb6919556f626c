"""End-to-end: a diffuse plane under area, directional-area, spot and sphere lights rendered by the
path tracer (NEE + BSDF hits with MIS) against closed forms or quadrature, region by region."""
import numpy as np
import pytest

from backend.materials import load_all as load_materials

from lights_util import rect_irradiance_parallel
from render_util import look_down_ortho, region_means, render, scene

K_SIGMA = 4.0
SIZE, HALF, RHO = 24, 1.5, 0.5

pytestmark = pytest.mark.skipif("diffuse" not in load_materials(), reason="needs the diffuse material")


def plane_scene(light, spp):
    return scene(SIZE, SIZE, look_down_ortho(HALF, height=5.0), {"grey": {"type": "diffuse", "color": RHO}},
                 {"plane": {"shape": "rectangle", "size": [2 * HALF + 1, 2 * HALF + 1]}},
                 [{"mesh": "plane", "materials": ["grey"]}], lights=[light],
                 render={"spp": spp, "max_bounces": 0, "seed": 5}, film_filter={"type": "box", "width": 1.0})


def footprint(sub=3):
    """World (x, y) of sub×sub points in every pixel, shape (SIZE, SIZE, sub*sub, 2); row 0 = +Y."""
    offs = (np.arange(sub) + 0.5) / sub
    px = (np.arange(SIZE)[:, None] + offs[None, :]).ravel() / SIZE
    x = -HALF + 2 * HALF * px
    y = HALF - 2 * HALF * px
    X = np.broadcast_to(x.reshape(1, SIZE, 1, sub), (SIZE, SIZE, sub, sub))
    Y = np.broadcast_to(y.reshape(SIZE, 1, sub, 1), (SIZE, SIZE, sub, sub))
    return np.stack([X, Y], -1).reshape(SIZE, SIZE, sub * sub, 2)


def check(result, expected_radiance):
    img = result.film.combined()[..., 0]
    var = result.film.variance_of_mean()[..., 0]
    for _, _, mean, se, (ys, xs) in region_means(img[..., None], var[..., None], np.ones(img.shape, bool), 4):
        exp = expected_radiance[ys, xs].mean()
        # 2e-3: error of the per-pixel footprint quadrature of the reference
        assert abs(mean[0] - exp) <= K_SIGMA * se[0] + 2e-3 * exp, (mean, exp, se)


def test_rectangle_area_light():
    h, lx, ly, P = 1.0, 1.2, 0.8, 20.0
    light = {"type": "area", "to_world": [[1, 0, 0, 0.2], [0, 1, 0, 0], [0, 0, 1, h], [0, 0, 0, 1]],
             "shape": "rectangle", "size": lx, "size_y": ly, "power": P}
    result = render(plane_scene(light, 32))
    L = P / (np.pi * lx * ly)
    fp = footprint()
    e = np.vectorize(lambda x, y: rect_irradiance_parallel(-lx / 2 + 0.2 - x, lx / 2 + 0.2 - x,
                                                           -ly / 2 - y, ly / 2 - y, h, L))(fp[..., 0], fp[..., 1])
    check(result, RHO / np.pi * e.mean(axis=-1))


def test_directional_area_light():
    """cutoff 30°, beam 10° at height 0.8: quadrature of L0 f(θ)/K cos² θ / t² over the emitter."""
    h, lx, ly, P = 0.8, 0.6, 0.6, 10.0
    c, b = np.radians(30), np.radians(10)
    light = {"type": "area", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, h], [0, 0, 0, 1]],
             "shape": "square", "size": lx, "power": P, "cutoff_angle": 30, "beam_width": 10}
    result = render(plane_scene(light, 32))
    th = np.linspace(0, np.pi / 2, 200001)
    s = np.clip((c - th) / (c - b), 0, 1)
    f = np.where(th <= b, 1, np.where(th >= c, 0, s * s * (3 - 2 * s)))
    K = np.trapz(2 * f * np.cos(th) * np.sin(th), th)
    L0 = P / (np.pi * lx * ly * K)
    k = 60
    g = ((np.arange(k) + 0.5) / k - 0.5) * lx
    EX, EY = np.meshgrid(g, g)
    fp = footprint(2).reshape(-1, 2)
    dx = EX.ravel()[None, :] - fp[:, :1]
    dy = EY.ravel()[None, :] - fp[:, 1:]
    t2 = dx * dx + dy * dy + h * h
    cos = h / np.sqrt(t2)
    theta = np.arccos(cos)
    ss = np.clip((c - theta) / (c - b), 0, 1)
    ff = np.where(theta <= b, 1, np.where(theta >= c, 0, ss * ss * (3 - 2 * ss)))
    e = (L0 * ff * cos * cos / t2).sum(axis=1) * (lx * ly) / (k * k)
    check(result, RHO / np.pi * e.reshape(SIZE, SIZE, 4).mean(axis=-1))


def test_sphere_light():
    """A sphere light's irradiance is exactly I cos θ / d² wherever it is fully above the horizon."""
    h, r, P = 1.0, 0.25, 30.0
    light = {"type": "point", "to_world": [[1, 0, 0, 0.1], [0, 1, 0, -0.1], [0, 0, 1, h], [0, 0, 0, 1]],
             "power": P, "radius": r}
    result = render(plane_scene(light, 32))
    fp = footprint()
    dx, dy = 0.1 - fp[..., 0], -0.1 - fp[..., 1]
    d2 = dx * dx + dy * dy + h * h
    e = P / (4 * np.pi) * (h / np.sqrt(d2)) / d2
    # fully visible where the cap's edge is above the horizon: asin(r/d) + θ < 90°
    ok = np.arcsin(r / np.sqrt(d2)) + np.arccos(h / np.sqrt(d2)) < np.pi / 2
    assert ok.all()
    check(result, RHO / np.pi * e.mean(axis=-1))
