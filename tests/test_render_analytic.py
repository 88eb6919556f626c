"""End-to-end renders against closed forms: white furnace, point light and sun irradiance,
and bit-identical results for any worker count."""
import numpy as np
import pytest

from render_util import front_perspective, look_down_ortho, region_means, render, scene

K_SIGMA = 4.0


def furnace_scene(material, spp=32, size=48):
    return scene(size, size, front_perspective(distance=4.0, half_width=0.3),
                 {"m": material}, {"ball": {"shape": "sphere", "radius": 1.0, "segments": 64}},
                 [{"mesh": "ball", "materials": ["m"]}],
                 world={"type": "constant", "color": [0.5, 0.5, 0.5], "strength": 1.0},
                 render={"spp": spp, "max_bounces": 64, "rr_depth": 64, "seed": 7})


def check_furnace(result, expected=0.5):
    img = result.film.combined()
    var = result.film.variance_of_mean()
    assert np.all(np.isfinite(img))
    regions = region_means(img, var, np.ones(img.shape[:2], bool), 6)
    for _, _, mean, se, _ in regions:
        # Pixels of a lossless object in a uniform environment equal the environment.
        assert np.all(np.abs(mean - expected) <= K_SIGMA * se + 1e-9), (mean, se)
    return regions


def test_white_furnace_diffuse():
    result = render(furnace_scene({"type": "diffuse", "color": 1.0}))
    regions = check_furnace(result)
    # The test has power: the per-region standard error is small compared to the signal.
    assert max(r[3].max() for r in regions) < 0.01


def test_white_furnace_conductor_with_unit_fresnel():
    # eta = 0, k huge gives |F| = 1 in the conductor Fresnel formula: a perfect mirror.
    mirror = {"type": "conductor", "eta": [0.0, 0.0, 0.0], "k": [1e4, 1e4, 1e4], "roughness": 0.0}
    result = render(furnace_scene(mirror, spp=8))
    img = result.film.combined()
    assert np.allclose(img, 0.5, atol=1e-3)


def test_rough_conductor_furnace_reports_energy_loss():
    """Single-scattering microfacets lose energy at high roughness: never gain."""
    rough = {"type": "conductor", "eta": [0.0, 0.0, 0.0], "k": [1e4, 1e4, 1e4], "roughness": 0.5}
    result = render(furnace_scene(rough, spp=32))
    img = result.film.combined()
    var = result.film.variance_of_mean()
    for _, _, mean, se, _ in region_means(img, var, np.ones(img.shape[:2], bool), 6):
        assert np.all(mean <= 0.5 + K_SIGMA * se)


def plane_scene(light, size=32, spp=64, half=2.0, albedo=0.5):
    return scene(size, size, look_down_ortho(half, height=5.0),
                 {"grey": {"type": "diffuse", "color": albedo}},
                 {"plane": {"shape": "rectangle", "size": [2 * half + 1, 2 * half + 1]}},
                 [{"mesh": "plane", "materials": ["grey"]}], lights=[light],
                 render={"spp": spp, "max_bounces": 0, "seed": 3},
                 film_filter={"type": "box", "width": 1.0})


def pixel_footprint_points(size, half, sub=4):
    """World (x, y) of a sub×sub grid inside every pixel (row 0 = top = +Y)."""
    offs = (np.arange(sub) + 0.5) / sub
    px = (np.arange(size)[:, None] + offs[None, :]).ravel() / size
    x = -half + 2 * half * px
    y = half - 2 * half * px
    X = x.reshape(size, sub)
    Y = y.reshape(size, sub)
    return X, Y


def analytic_image(size, half, func, sub=4):
    X, Y = pixel_footprint_points(size, half, sub)
    xs = X[None, :, None, :]
    ys = Y[:, None, :, None]
    vals = func(np.broadcast_to(xs, (size, size, sub, sub)), np.broadcast_to(ys, (size, size, sub, sub)))
    return vals.mean(axis=(2, 3))


def test_diffuse_plane_under_point_light_matches_irradiance():
    P, h, rho = 100.0, 1.5, 0.5
    light = {"type": "point", "to_world": [[1, 0, 0, 0.3], [0, 1, 0, -0.2], [0, 0, 1, h], [0, 0, 0, 1]],
             "power": P, "color": [1, 1, 1], "radius": 0.0}
    result = render(plane_scene(light, spp=16))
    img = result.film.combined()[:, :, 1]
    var = result.film.variance_of_mean()[:, :, 1]

    def radiance(x, y):
        dx, dy = x - 0.3, y + 0.2
        r2 = dx * dx + dy * dy + h * h
        return rho / np.pi * P / (4 * np.pi) * (h / np.sqrt(r2)) / r2   # L = ρ/π · I cosθ / r²

    ref = analytic_image(32, 2.0, radiance)
    # With a delta light each sample is exact at its position; the only noise is where in the
    # pixel the samples fell, measured by the variance pass.
    ones = np.ones(img.shape, bool)
    for (by, bx, mean, se, (ys, xs)), in zip(region_means(img[..., None], var[..., None], ones, 4)):
        expected = ref[ys, xs].mean()
        assert abs(mean[0] - expected) <= K_SIGMA * se[0] + 1e-9 * expected, (by, bx, mean, expected, se)


def test_diffuse_plane_under_sun_matches_irradiance():
    E, rho = 3.0, 0.5
    tilt = np.radians(30.0)
    # Sun pointing down its local −Z, rotated 30° about X.
    c, s = np.cos(tilt), np.sin(tilt)
    light = {"type": "sun", "to_world": [[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 10], [0, 0, 0, 1]],
             "strength": E, "color": [1, 1, 1], "angle": 0.0}
    result = render(plane_scene(light, spp=4))
    img = result.film.combined()
    assert np.allclose(img, rho / np.pi * E * c, rtol=1e-4)


def test_sun_with_angle_matches_irradiance_within_noise():
    E, rho = 3.0, 0.5
    light = {"type": "sun", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 10], [0, 0, 0, 1]],
             "strength": E, "color": [1, 1, 1], "angle": 10.0}
    result = render(plane_scene(light, spp=32))
    img = result.film.combined()
    var = result.film.variance_of_mean()
    # Cycles gives the sun disk the radiance E/(π sin²(angle/2)); a plane facing the disk centre
    # then receives ∫cosθ dω · L = π sin²(angle/2) · L = E exactly.
    expected = rho / np.pi * E
    for _, _, mean, se, _ in region_means(img, var, np.ones(img.shape[:2], bool), 4):
        assert np.all(np.abs(mean - expected) <= K_SIGMA * se + 1e-6 * expected), (mean, expected, se)


@pytest.mark.parametrize("workers", [2])
def test_same_image_for_any_worker_count(workers):
    data = furnace_scene({"type": "diffuse", "color": 0.7}, spp=8, size=40)
    data["render"]["max_bounces"] = 4
    data["render"]["rr_depth"] = 1
    one = render(data, workers=1)
    many = render(data, workers=workers)
    assert one.spp_done == many.spp_done == 8
    assert np.array_equal(one.film.sum, many.film.sum)
    assert np.array_equal(one.film.sum_sq, many.film.sum_sq)
    assert np.array_equal(one.film.count, many.film.count)


def test_no_light_leaks_into_a_closed_box():
    """Camera inside a closed cube, bright sun and sky outside: every pixel must be exactly black."""
    sun = {"type": "sun", "to_world": [[1, 0, 0, 0], [0, 0.6, -0.8, 0], [0, 0.8, 0.6, 10], [0, 0, 0, 1]],
           "strength": 1000.0, "color": [1, 1, 1], "angle": 3.0}
    data = scene(32, 32, front_perspective(distance=0.5, half_width=0.8),
                 {"wall": {"type": "diffuse", "color": 0.9}},
                 {"box": {"shape": "cube", "size": 2.0}},
                 [{"mesh": "box", "materials": ["wall"]}], lights=[sun],
                 world={"type": "constant", "color": [1, 1, 1], "strength": 100.0},
                 render={"spp": 16, "max_bounces": 6, "seed": 2})
    result = render(data)
    assert result.film.combined().max() == 0.0


@pytest.mark.parametrize("tilt_deg", [60.0, 85.0])
def test_no_shadow_acne_at_grazing_sun(tilt_deg):
    """A plane lit at grazing incidence: any self-intersection would show as dark pixels."""
    E, rho = 3.0, 0.5
    c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
    light = {"type": "sun", "to_world": [[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 10], [0, 0, 0, 1]],
             "strength": E, "color": [1, 1, 1], "angle": 0.0}
    data = plane_scene(light, spp=4)
    # Move plane and camera ~1 km from the origin: float32 precision there must not cause acne either.
    far = np.array([800.0, -600.0, 150.0])
    data["objects"][0]["to_world"] = [[1, 0, 0, far[0]], [0, 1, 0, far[1]], [0, 0, 1, far[2]], [0, 0, 0, 1]]
    cam = np.array(data["camera"]["to_world"], float)
    cam[:3, 3] += far
    data["camera"]["to_world"] = cam.tolist()
    result = render(data)
    assert np.allclose(result.film.combined(), rho / np.pi * E * c, rtol=1e-4)


def test_transparent_film_and_holdout_alpha():
    """Film > Transparent: the world seen directly is transparent; holdouts are black holes."""
    data = furnace_scene({"type": "diffuse", "color": 0.8}, spp=4, size=32)
    data["film"]["transparent"] = True
    data["meshes"]["card"] = {"shape": "rectangle", "size": [0.6, 0.6]}
    # A holdout card in front of the sphere's centre, facing the camera (−Y).
    data["objects"].append({"mesh": "card", "holdout": True, "materials": ["m"],
                            "to_world": [[1, 0, 0, 0], [0, 0, -1, -1.5], [0, 1, 0, 0], [0, 0, 0, 1]]})
    result = render(data)
    film = result.film
    cov = film.coverage()
    img = film.combined()
    # corners see the world only: alpha 0 and no world radiance; the centre sees the holdout card.
    assert cov[0, 0] == 0 and np.all(img[0, 0] == 0)
    assert cov[16, 16] == 0 and np.all(img[16, 16] == 0)
    # between the card and the silhouette the sphere is opaque and lit.
    assert cov[16, 5] == 1 and img[16, 5].min() > 0
