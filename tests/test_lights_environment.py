"""World lights: Blender's equirectangular orientation, irradiance vs brute-force quadrature of the
image over the sphere, importance-sampling density vs pdf_escaped, constant world, texel hygiene."""
import json

import numpy as np
import pytest

from backend.lights.environment import ConstantWorld, EnvironmentMap
from backend.scene.loader import load_scene_data

from lights_util import K_SIGMA, chi2_pvalue, nee_irradiance, rot_z


def blender_uv(d):
    """Cycles direction_to_equirectangular: u = 0.5 − atan2(y, x)/2π, v = 1 − acos(z)/π."""
    return 0.5 - np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi), 1 - np.arccos(np.clip(d[:, 2], -1, 1)) / np.pi


def bilinear(img, u, v):
    """Texel centres at (i + 0.5)/W; v up (row 0 of the image is the top); wrap u, clamp v."""
    h, w = img.shape[:2]
    x = np.mod(u, 1.0) * w - 0.5
    y = np.clip((1 - v) * h - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    y1 = np.minimum(y0 + 1, h - 1)
    return ((img[y0, x0 % w] * (1 - fx) + img[y0, (x0 + 1) % w] * fx) * (1 - fy)
            + (img[y1, x0 % w] * (1 - fx) + img[y1, (x0 + 1) % w] * fx) * fy)


def test_orientation_matches_blender():
    h, w = 8, 16
    # ask where the pixel of each direction lands, via a one-hot image per direction
    for d, (row, col) in {(1, 0, 0): (h // 2, w // 2), (0, 1, 0): (h // 2, w // 4),
                          (-1, 0, 0): (h // 2, 0), (0, -1, 0): (h // 2, 3 * w // 4),
                          (0, 0, 1): (0, None)}.items():
        d = np.array([d], float)
        one = np.zeros((h, w, 3))
        if col is None:
            one[row, :] = 1.0
        else:
            for r in (row - 1, row):                          # the four texels around it
                for c in (col - 1, col):
                    one[r, c % w] = 1.0
        env = EnvironmentMap(one)
        assert env.eval_escaped(d)[0, 0] == pytest.approx(1.0), d


def test_to_world_rotates_the_map():
    rng = np.random.default_rng(30)
    img = rng.random((16, 32, 3))
    m = np.eye(4)
    m[:3, :3] = rot_z(90)
    env = EnvironmentMap(img, 1.0, m)
    d = rng.normal(size=(100, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    # world direction d looks up the map at R⁻¹ d
    local = d @ rot_z(90)            # rows: (Rᵀ d)ᵀ
    u, v = blender_uv(local)
    assert np.allclose(env.eval_escaped(d), bilinear(img, u, v), rtol=1e-12)


def quadrature_irradiance(img, strength, normal, k=(720, 1440)):
    """E = ∫ L(ω) max(cos, 0) dω on a (θ, φ) midpoint grid, with the bilinear lookup above."""
    nt, nphi = k
    th = (np.arange(nt) + 0.5) * np.pi / nt
    ph = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1).reshape(-1, 3)
    u, v = blender_uv(d)
    L = bilinear(img, u, v) * strength
    w = (np.sin(TH).ravel() * np.maximum(d @ normal, 0))[:, None] * (np.pi / nt) * (2 * np.pi / nphi)
    return (L * w).sum(axis=0)


def test_environment_irradiance_matches_quadrature():
    rng = np.random.default_rng(31)
    h, w = 24, 48
    img = 0.2 * rng.random((h, w, 3))
    img[5:8, 30:34] = [40.0, 30.0, 20.0]          # a small bright "sun" region
    img[h - 3:, :] = 0.0                          # black ground near the bottom pole
    env = EnvironmentMap(img, 1.5)
    for normal in ([0, 0, 1.0], [0.6, -0.3, 0.74], [0, 0, -1.0]):
        normal = np.array(normal) / np.linalg.norm(normal)
        ref = quadrature_irradiance(img, 1.5, normal)
        mean, se, s = nee_irradiance(env, np.zeros(3), normal, 100000, rng)
        assert np.all(np.abs(mean - ref) <= K_SIGMA * se + 2e-4 * ref), (normal, mean, ref, se)


def test_environment_sampling_density_matches_pdf_escaped():
    """Chi-square on texel bins (θ, φ cells of the image, located with Blender's formula): the
    expected probability of a texel is pdf_escaped × sin θ Δθ Δφ (exact: pdf_ω sin θ is constant
    in a texel)."""
    rng = np.random.default_rng(32)
    h, w = 16, 32
    img = rng.random((h, w, 3)) ** 4 * 5
    img[3, 7] = 200.0
    env = EnvironmentMap(img, 1.0)
    rows, cols = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    th = (rows.ravel() + 0.37) * np.pi / h           # any point inside the texel
    u = (cols.ravel() + 0.61) / w
    phi = np.pi - 2 * np.pi * u                      # inverse of u = 0.5 − φ/2π
    d = np.stack([np.sin(th) * np.cos(phi), np.sin(th) * np.sin(phi), np.cos(th)], -1)
    expected = env.pdf_escaped(d) * np.sin(th) * (np.pi / h) * (2 * np.pi / w)
    assert expected.sum() == pytest.approx(1.0, rel=1e-12)
    n = 200000
    s = env.sample(np.zeros((n, 3)), rng.random((n, 2)))
    su, sv = blender_uv(s.wi)
    r = np.clip(((1 - sv) * h).astype(int), 0, h - 1)
    c = np.clip((np.mod(su, 1) * w).astype(int), 0, w - 1)
    observed = np.bincount(r * w + c, minlength=h * w)
    assert chi2_pvalue(observed, expected * n) > 0.01
    assert np.allclose(env.pdf_escaped(s.wi), s.pdf, rtol=1e-9)
    assert np.allclose(env.eval_escaped(s.wi) / s.pdf[:, None], s.value, rtol=1e-9)


def test_every_lit_direction_has_positive_pdf():
    """Bilinear radiance reaches one texel beyond bright texels: the sampling density must too."""
    img = np.zeros((8, 16, 3))
    img[4, 5] = 1.0
    env = EnvironmentMap(img)
    rng = np.random.default_rng(33)
    d = rng.normal(size=(200000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    lit = env.eval_escaped(d)[:, 0] > 0
    assert lit.any() and np.all(env.pdf_escaped(d[lit]) > 0)


def test_constant_world():
    world = ConstantWorld([0.5, 1.0, 2.0])
    rng = np.random.default_rng(34)
    mean, se, s = nee_irradiance(world, np.zeros(3), [0, 0, 1.0], 100000, rng)
    assert np.all(np.abs(mean - np.pi * np.array([0.5, 1.0, 2.0])) <= K_SIGMA * se)
    world.prepare(np.zeros(3), 2.0)
    assert world.power() == pytest.approx(4 * np.pi ** 2 * 4.0 * (0.5 * 0.2126 + 0.7152 + 2 * 0.0722))


def write_exr(path, pixels):
    import OpenImageIO as oiio
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], oiio.FLOAT)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image(pixels.astype(np.float32))
    out.close()


BASE = {
    "format": "lamina-scene", "version": 1, "film": {"width": 4, "height": 4},
    "camera": {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0, -1, -5], [0, 1, 0, 0], [0, 0, 0, 1]],
               "frame": [[0.36, 0.27, -1], [0.36, -0.27, -1], [-0.36, -0.27, -1], [-0.36, 0.27, -1]]},
}


def test_environment_file_sanitised_with_warnings(tmp_path):
    px = np.ones((4, 8, 4), np.float32)
    px[0, 0, 0] = np.nan
    px[1, 2, 1] = -3.0
    px[2, 3, 2] = np.inf
    write_exr(tmp_path / "sky.exr", px)
    data = dict(BASE, world={"type": "environment", "file": "sky.exr", "strength": 2.0})
    scene = load_scene_data(json.loads(json.dumps(data)), "scene.json", tmp_path)
    env = scene.world
    assert np.all(np.isfinite(env.texels)) and np.all(env.texels >= 0)
    assert env.texels[0, 0, 0] == 0 and env.texels[1, 2, 1] == 0 and env.texels[2, 3, 2] == 0
    assert env.texels[3, 3, 0] == 2.0           # strength applied, alpha dropped
    text = " ".join(scene.warnings)
    assert "NaN/Inf" in text and "negative" in text and "world.file" in text
