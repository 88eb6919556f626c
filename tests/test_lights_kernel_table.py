"""The compiled light interface (backend/kernels/lights/dispatch.py) on one table holding lights of
every kind, through its batch loops: the density ``sample`` reports is the one ``pdf_hit`` /
``pdf_escaped`` / ``mesh_pdf_hit`` give for the sampled direction, the value is the radiance over
that density (the exact texture lookup for a textured mesh emitter), and light selection's
probabilities sum to one per point and match their sampling, also with 64 lights."""
from pathlib import Path

import numpy as np
import pytest
from scipy import stats as sst

from backend.ies.light import IESEmission
from backend.ies.profile import IESProfile
from backend.kernels.lights import batch
from backend.kernels.lights.table import build_light_table, light_count
from backend.kernels.params import ParamPacker
from backend.lights.area import AreaLight, CollimatedAreaLight
from backend.lights.environment import ConstantWorld, EnvironmentMap
from backend.lights.mesh import MeshLight
from backend.lights.point import PointLight
from backend.lights.profiles import CyclesSpread, SmoothCone
from backend.lights.spot import SpotLight
from backend.lights.sun import SunLight
from backend.textures import ImageParam

from lights_util import rot_x, rot_z, translate

IES = Path(__file__).parent / "data" / "ies" / "hew_overhead_quad90_8lamps_lm95.ies"
RTOL = 1e-6

# A textured two-sided emitter: a quad at z = 2.5 facing down, UVs over the unit square.
QUAD = np.array([[[-0.4, -0.3, 2.5], [0.4, -0.3, 2.5], [0.4, 0.3, 2.5]],
                 [[-0.4, -0.3, 2.5], [0.4, 0.3, 2.5], [-0.4, 0.3, 2.5]]])
QUAD_UV = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float)


def scene_lights():
    rng = np.random.default_rng(5)
    texels = (0.2 + rng.random((6, 8, 3)) * 3).astype(np.float32)
    emission = ImageParam(texels, 3, np.array([2.0, 1.5, 1.0]), "test")
    radiance = emission.bind(QUAD_UV.mean(axis=1))
    mesh = MeshLight(QUAD, radiance, two_sided=True, uvs=QUAD_UV, emission=[emission], slots=[0, 0])
    mesh.triangle_ids = np.array([7, 3])
    env = EnvironmentMap(rng.random((12, 24, 3)) ** 3 * 4, 1.2, translate(0, 0, 0, rot_z(30)))
    lights = [
        AreaLight(translate(0.3, -0.2, 2.0, rot_x(10)), "rectangle", 1.2, 0.8, 40.0, [1, 0.9, 0.8],
                  True, SmoothCone(np.radians(35), np.radians(10)), visible_camera=True),
        AreaLight(translate(-1.0, 0.5, 1.8, rot_z(25)), "ellipse", 0.9, 0.5, 20.0, [1, 1, 1], True,
                  CyclesSpread(np.radians(70))),
        SpotLight(translate(1.0, 1.0, 3.0, rot_x(15)), 60.0, [1, 0.8, 0.6], np.radians(70), 0.3,
                  profile=IESEmission(IESProfile.from_file(IES))),
        PointLight(translate(-0.5, -1.0, 1.5), 30.0, [1, 1, 1], radius=0.3),             # sphere
        PointLight(translate(0.8, -0.9, 1.2), 25.0, [1, 1, 1], radius=0.2, soft_falloff=True),
        SunLight(translate(0, 0, 0, rot_x(30)), 3.0, [1, 1, 0.9], np.radians(5.0), visible_camera=True),
        env,
        mesh,
        CollimatedAreaLight(translate(0, 0, 3.0), "square", 2.0, 2.0, 10.0, [1, 1, 1]),
        ConstantWorld([0.05, 0.06, 0.07]),
    ]
    for light in lights:
        light.prepare(np.zeros(3), 5.0)
    return lights


@pytest.fixture(scope="module")
def table():
    lights = scene_lights()
    packer = ParamPacker()
    lt = build_light_table(lights, packer, 5.0, "local")
    return lights, lt, packer.table()


def ray_triangles(o, d, tris):
    """Nearest hit of rays (o, d) on the triangles (Möller–Trumbore): (t, triangle, b1, b2)."""
    best = np.full(o.shape[0], np.inf)
    tri = np.full(o.shape[0], -1)
    bb = np.zeros((o.shape[0], 2))
    for k, v in enumerate(tris):
        e1, e2 = v[1] - v[0], v[2] - v[0]
        pv = np.cross(d, e2)
        det = pv @ e1
        inv = 1.0 / np.where(det != 0, det, 1.0)
        tv = o - v[0]
        b1 = np.einsum("ij,ij->i", tv, pv) * inv
        qv = np.cross(tv, e1)
        b2 = np.einsum("ij,ij->i", d, qv) * inv
        t = (qv @ e2) * inv
        ok = (det != 0) & (b1 >= -1e-9) & (b2 >= -1e-9) & (b1 + b2 <= 1 + 1e-9) & (t > 0) & (t < best)
        best = np.where(ok, t, best)
        tri = np.where(ok, k, tri)
        bb[ok] = np.column_stack([b1, b2])[ok]
    return best, tri, bb


def test_table_layout(table):
    lights, lt, _ = table
    assert light_count(lt) == len(lights)
    assert list(lt.hittable) == [i for i, l in enumerate(lights) if l.is_hittable]
    assert list(lt.infinite) == [i for i, l in enumerate(lights) if l.is_infinite]
    assert list(lt.is_delta) == [bool(l.is_delta) for l in lights]
    # the mesh light's primitives 7 and 3 are its triangles 0 and 1
    assert lt.prim_light[7] == 7 and lt.prim_local[7] == 0 and lt.prim_local[3] == 1
    assert lt.prim_light[0] == -1 and lt.prim_light.size == 8


def test_sample_density_equals_hit_density(table):
    """(a) For every light and lane with a sample: pdf == pdf_hit / pdf_escaped / mesh_pdf_hit of
    the sampled direction (relative 1e-6), and value == emitted radiance / pdf."""
    lights, lt, tx = table
    rng = np.random.default_rng(1)
    # points all over, and close under the two area lights (where their cutoff cones are
    # sampled rather than a clipped rectangle or the whole ellipse)
    k = 1500
    p = np.concatenate([
        np.column_stack([rng.uniform(-1.5, 1.5, k), rng.uniform(-1.5, 1.5, k), rng.uniform(-0.5, 1.4, k)]),
        np.column_stack([rng.uniform(-0.2, 0.8, k), rng.uniform(-0.6, 0.2, k), rng.uniform(1.5, 1.9, k)]),
        np.column_stack([rng.uniform(-1.3, -0.7, k), rng.uniform(0.3, 0.7, k), rng.uniform(1.5, 1.75, k)])])
    n = p.shape[0]
    u = rng.random((n, 2))
    for li, light in enumerate(lights):
        lanes = np.array([li], np.int64)
        wi, dist, value, pdf, delta = np.empty((n, 3)), np.empty(n), np.empty((n, 3)), np.empty(n), np.empty(n, bool)
        batch.sample(lt, tx, lanes, p, u, wi, dist, value, pdf, delta)
        assert np.all(delta == bool(light.is_delta)) and np.all(np.isfinite(value)), li
        if light.is_delta:
            assert np.all(pdf == 0) and np.any(value > 0), li
            continue
        ok = pdf > 0
        assert ok.mean() > 0.05, (li, ok.mean())
        o, d, pd, val = p[ok], wi[ok], pdf[ok], value[ok]
        m = o.shape[0]
        if light.is_infinite:
            got, le = np.empty(m), np.empty((m, 3))
            batch.pdf_escaped(lt, lanes, d, got)
            batch.eval_escaped(lt, lanes, d, le)
            assert np.all(np.isinf(dist[ok]))
        elif isinstance(light, MeshLight):
            t, tri, bary = ray_triangles(o, d, QUAD)
            assert np.all(tri >= 0) and np.allclose(t, dist[ok], rtol=1e-9)
            got = np.empty(m)
            batch.mesh_pdf_hit(lt, lanes, o, d, t, tri.astype(np.int64), got)
            # exact textured emission at the hit: the emission parameter at the interpolated UV
            w = np.column_stack([1 - bary.sum(1), bary])
            uv = np.einsum("nij,ni->nj", QUAD_UV[tri], w)
            le = light.emission[0].bind(uv)
        else:
            t = np.empty(m)
            batch.intersect(lt, lanes, o, d, np.full(m, np.inf), t)
            assert np.all(np.isfinite(t)), li
            assert np.allclose(t, dist[ok], rtol=1e-7), li
            got, le = np.empty(m), np.empty((m, 3))
            batch.pdf_hit(lt, lanes, o, d, t, got)
            batch.eval_hit(lt, lanes, o, d, t, le)
        np.testing.assert_allclose(got, pd, rtol=RTOL, err_msg=f"light {li}")
        np.testing.assert_allclose(le / pd[:, None], val, rtol=RTOL, err_msg=f"light {li}")


def check_selection(lt, points, n_draw, rng):
    """(b) Per point: probabilities over all lights sum to 1, the ones ``select`` reports equal
    ``select_prob``, zero-power lights are never drawn, and the draws follow the probabilities."""
    count = light_count(lt)
    for point in points:
        probs = np.empty(count)
        one = np.asarray(point, float)[None, :]
        for li in range(count):
            out = np.empty(1)
            batch.select_prob(lt, one, np.array([li], np.int64), out)
            probs[li] = out[0]
        assert abs(probs.sum() - 1.0) < 1e-12, probs.sum()
        pts = np.repeat(one, n_draw, axis=0)
        idx, prob = np.empty(n_draw, np.int64), np.empty(n_draw)
        batch.select(lt, pts, rng.random(n_draw), idx, prob)
        assert np.all(idx >= 0)
        np.testing.assert_allclose(prob, probs[idx], rtol=1e-12)
        counts = np.bincount(idx, minlength=count)
        assert np.all(counts[probs == 0] == 0)
        pos = probs * n_draw >= 5
        assert counts[~pos].sum() <= max(10, 10 * probs[~pos].sum() * n_draw)
        expected = probs[pos] * n_draw
        expected *= counts[pos].sum() / expected.sum()
        if pos.sum() > 1:
            assert sst.chisquare(counts[pos], expected).pvalue > 1e-3


def test_selection_over_the_mixed_table(table):
    _, lt, _ = table
    rng = np.random.default_rng(2)
    check_selection(lt, [[0.1, 0.2, 0.0], [0.3, -0.2, 2.4], [-2.0, 1.0, 0.5]], 40000, rng)


@pytest.mark.parametrize("mode", ["local", "power"])
def test_selection_with_64_lights(mode):
    """(c) 64 lights of several kinds, some emitting nothing; a loop over lights per lane."""
    rng = np.random.default_rng(3)
    lights = []
    for k in range(64):
        pos = rng.uniform(-4, 4, 3)
        watts = 0.0 if k % 9 == 4 else float(rng.uniform(1, 100))
        if k % 4 == 0:
            lights.append(AreaLight(translate(*pos, rot_x(rng.uniform(0, 180))), "square", 0.5, 0.5, watts,
                                    [1, 1, 1]))
        elif k % 4 == 1:
            lights.append(PointLight(translate(*pos), watts, [1, 0.5, 0.2], radius=0.1 * (k % 3)))
        elif k % 4 == 2:
            lights.append(SpotLight(translate(*pos), watts, [1, 1, 1], np.radians(60), 0.2))
        else:
            lights.append(SunLight(translate(0, 0, 0, rot_x(rng.uniform(0, 60))), watts / 50, [1, 1, 1]))
        lights[-1].prepare(np.zeros(3), 6.0)
    lt = build_light_table(lights, ParamPacker(), 6.0, mode)
    assert light_count(lt) == 64 and lt.sel_active.size == 64 - 7
    assert lt.local_selection == (mode == "local")
    points = rng.uniform(-3, 3, (4, 3))
    check_selection(lt, points, 60000, rng)
    # many points at once: per-lane probabilities of every light sum to 1
    p = rng.uniform(-5, 5, (500, 3))
    total = np.zeros(500)
    out = np.empty(500)
    for li in range(64):
        batch.select_prob(lt, p, np.array([li], np.int64), out)
        total += out
    np.testing.assert_allclose(total, 1.0, rtol=1e-12)


def test_no_emitting_light_selects_nothing():
    lt = build_light_table([PointLight(translate(0, 0, 1), 0.0, [1, 1, 1])], ParamPacker(), 1.0, "local")
    idx, prob = np.empty(3, np.int64), np.empty(3)
    batch.select(lt, np.zeros((3, 3)), np.array([0.0, 0.5, 0.99]), idx, prob)
    assert np.all(idx == -1) and np.all(prob == 0)
    out = np.empty(3)
    batch.select_prob(lt, np.zeros((3, 3)), np.array([0], np.int64), out)
    assert np.all(out == 0)
