"""IES light: irradiance from sample() vs the table evaluated independently, orientation, power,
spot cone, scene parsing."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from backend.errors import SceneError
from backend.ies.lm63 import read_lm63
from backend.ies.light import IESEmission
from backend.lights.point import PointLight
from backend.lights.spot import SpotLight, spot_attenuation
from backend.ies.profile import IESProfile
from backend.scene.reader import LoadContext, Node, dispatch
from ies_reference import ReferenceProfile, rotation_matrix

IES_DIR = Path(__file__).parent / "data" / "ies"
EFFICACY = 177.83  # lm/W, docs/lights.md, IES lights


def _to_world(R, t, scale=(1.0, 1.0, 1.0)):
    M = np.eye(4)
    M[:3, :3] = R @ np.diag(scale)
    M[:3, 3] = t
    return M


def ies_light(profile, to_world, power, color=(1.0, 1.0, 1.0), spot_size_deg=None, spot_blend=0.0):
    """A point (or spot) light carrying the IES profile, as the scene parser builds it."""
    if spot_size_deg is None:
        return PointLight(to_world, power, color, profile=IESEmission(profile))
    return SpotLight(to_world, power, color, math.radians(spot_size_deg), spot_blend,
                     profile=IESEmission(profile))


def intensity(light, w_world):
    """Radiant intensity (n, 3) [W/sr] along world directions w, read through sample() from
    points at unit distance (I = E·r² with r = 1)."""
    w = np.asarray(w_world, dtype=np.float64).reshape(-1, 3)
    w = w / np.linalg.norm(w, axis=1, keepdims=True)
    return light.sample(light.position + w, np.zeros((w.shape[0], 2))).value


def _plane_points(n=41, z=0.0, half=6.0):
    g = np.linspace(-half, half, n)
    x, y = np.meshgrid(g, g)
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)


@pytest.mark.parametrize("name,axis,angle", [
    ("rab_asym360_45deg_lm02.ies", (1, 2, 3), 40.0),            # asymmetric 0..360
    ("qssi_roadway_typeIII_bilateral180_lm95.ies", (0, 1, 0), 25.0),   # bilateral
    ("hew_overhead_quad90_8lamps_lm95.ies", (0, 0, 1), 70.0),   # quadrilateral
    ("rab_ffled_flood_typeB_lm02.ies", (0, 1, 0), -90.0),       # type B aimed down
])
def test_irradiance_on_plane_matches_independent_table_evaluation(name, axis, angle):
    f = read_lm63(IES_DIR / name)
    R = rotation_matrix(axis, angle)
    pos = np.array([0.3, -0.2, 3.0])
    power, color = 60.0, np.array([1.0, 0.8, 0.5])
    light = ies_light(IESProfile(f), _to_world(R, pos), power, color)
    p = _plane_points()
    ls = light.sample(p, np.random.default_rng(0).random((p.shape[0], 2)))
    E = ls.value * ls.wi[:, 2:3]          # irradiance on the plane z = 0 (normal +Z)

    ref = ReferenceProfile(f)
    to_p = p - pos
    r2 = np.einsum("ij,ij->i", to_p, to_p)
    local = to_p @ R                        # R^T (p − pos): the direction in the light frame
    cd = np.array([ref.at_direction(d) for d in local])
    cos = -to_p[:, 2] / np.sqrt(r2)
    E_ref = (power * cd / EFFICACY * cos / r2)[:, None] * color[None, :]
    np.testing.assert_allclose(E, E_ref, rtol=1e-9, atol=1e-12 * E_ref.max())
    assert np.count_nonzero(E_ref[:, 0]) > 100
    assert np.all(ls.pdf == 0) and light.is_delta
    np.testing.assert_allclose(ls.dist, np.sqrt(r2))


def test_orientation_world_axes():
    """Light at the origin rotated 90° about +Z: local −Y (C0) → world +X, local −X (C90) → world −Y,
    local +Y (C180) → world −X, local +X (C270) → world +Y; −Z stays down."""
    f = read_lm63(IES_DIR / "rab_asym360_45deg_lm02.ies")
    R = rotation_matrix((0, 0, 1), 90.0)
    light = ies_light(IESProfile(f), _to_world(R, np.zeros(3)), EFFICACY)   # 1 W/sr per cd
    v = math.radians(60.0)
    s, c = math.sin(v), math.cos(v)
    H, V = list(f.horizontal_angles), list(f.vertical_angles)
    world = {0: [s, 0, -c], 90: [0, -s, -c], 180: [-s, 0, -c], 270: [0, s, -c]}
    for h, w in world.items():
        I = intensity(light, np.array([w]))[0, 0]
        assert I == pytest.approx(f.candela[H.index(h), V.index(60.0)] * f.factor, rel=1e-12)


def test_power_is_integrated_flux():
    f = read_lm63(IES_DIR / "rab_arbay2_asym360_lm02.ies")
    prof = IESProfile(f)
    color = np.array([0.9, 0.5, 0.2])
    light = ies_light(prof, _to_world(rotation_matrix((1, 1, 0), 33.0), [1, 2, 3]), 80.0, color)
    lum = 0.2126 * 0.9 + 0.7152 * 0.5 + 0.0722 * 0.2
    assert light.power() == pytest.approx(80.0 * prof.flux / EFFICACY * lum, rel=1e-12)
    # README flux for this file (bilinear, 13348 lm) → ≈ 80 W × 75 % emitted
    assert light.power() / lum / 80.0 == pytest.approx(13348 / EFFICACY, rel=0.01)


def _world_sphere_integral(light, n_theta=720, n_phi=1440):
    """∫ luminance(I(ω)) dω over *world* directions by a midpoint rule (independent of the
    light's own local-frame quadrature and Jacobian)."""
    th = (np.arange(n_theta) + 0.5) * math.pi / n_theta
    ph = (np.arange(n_phi) + 0.5) * 2 * math.pi / n_phi
    total = 0.0
    for k in range(0, n_theta, 90):
        t = th[k:k + 90]
        T, P = np.meshgrid(t, ph, indexing="ij")
        d = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
        I = intensity(light, d) @ np.array([0.2126, 0.7152, 0.0722])
        total += float((I.reshape(T.shape) * np.sin(T)).sum())
    return total * (math.pi / n_theta) * (2 * math.pi / n_phi)


def test_power_with_spot_and_nonuniform_scale():
    prof = IESProfile.from_file(IES_DIR / "hew_overhead_quad90_8lamps_lm95.ies")
    R = rotation_matrix((1, 0, 0), 30.0)
    scaled = ies_light(prof, _to_world(R, [0, 0, 2], scale=(2.0, 0.5, 1.0)), 10.0)
    brute = _world_sphere_integral(scaled)
    # midpoint rule at 0.25°: error well below 1e-3 for this smooth, wide distribution
    assert scaled.power() == pytest.approx(brute, rel=1e-3)
    # a non-uniform scale warps the distribution (Jacobian ≠ 1), so the emitted power changes:
    assert abs(scaled.power() - ies_light(prof, _to_world(R, [0, 0, 2]), 10.0).power()) > 1e-3 * brute
    spot = ies_light(prof, _to_world(R, [0, 0, 2]), 10.0, spot_size_deg=60.0, spot_blend=0.3)
    assert spot.power() == pytest.approx(_world_sphere_integral(spot), rel=1e-3)
    assert spot.power() < ies_light(prof, _to_world(R, [0, 0, 2]), 10.0).power()


def test_spot_attenuation_matches_cycles_formula():
    size, blend = 50.0, 0.25
    prof = IESProfile.from_file(IES_DIR / "rab_dled6_24lamps_axial_lm02.ies")
    light = ies_light(prof, np.eye(4), EFFICACY, spot_size_deg=size, spot_blend=blend)
    plain = ies_light(prof, np.eye(4), EFFICACY)
    ang = np.radians(np.array([0.0, 10.0, 20.0, 22.0, 24.0, 24.9, 25.1, 40.0]))
    d = np.stack([np.sin(ang), np.zeros_like(ang), -np.cos(ang)], axis=1)
    ratio = intensity(light, d)[:, 0] / intensity(plain, d)[:, 0]
    cos_half = math.cos(math.radians(size / 2))
    t = np.clip((np.cos(ang) - cos_half) / ((1 - cos_half) * blend), 0, 1)
    np.testing.assert_allclose(ratio, t * t * (3 - 2 * t), atol=1e-12)
    assert ratio[0] == 1.0 and ratio[-1] == 0.0 and ratio[-2] == 0.0
    hard = spot_attenuation(np.cos(ang), cos_half, np.inf)
    np.testing.assert_array_equal(hard, (np.degrees(ang) < size / 2).astype(float))


# ------------------------------------------------------------------ scene parsing

def _load_light(spec: dict, tmp_path: Path):
    from backend.lights import load_all
    registry, _ = load_all()
    ctx = LoadContext("scene.json", base_dir=tmp_path)
    node = Node({"lights": [spec]}, "", ctx)
    lights = node.child("lights").items()
    return dispatch(lights[0], registry), ctx


def _expected_irradiance_weight(prof, M, power, p, spot=None):
    """I(ω)/r² at points p from the table, the light at M (rotation + translation): (n,)."""
    R, pos = M[:3, :3], M[:3, 3]
    d = p - pos
    r2 = np.einsum("ij,ij->i", d, d)
    local = (d @ R) / np.sqrt(r2)[:, None]
    f = np.ones(p.shape[0])
    if spot is not None:
        size, blend = spot
        ch = math.cos(math.radians(size / 2))
        t = np.clip((-local[:, 2] - ch) / ((1 - ch) * blend), 0, 1)
        f = t * t * (3 - 2 * t)
    return power * prof.intensity(local) / EFFICACY * f / r2


def test_scene_point_and_spot_with_ies(tmp_path):
    """Whichever module builds it (backend.ies wrapper or the point/spot lights with an IES
    factor), a scene light with an "ies" field emits the table's intensity."""
    (tmp_path / "lamp.ies").write_bytes((IES_DIR / "rab_asym360_45deg_lm02.ies").read_bytes())
    M = _to_world(rotation_matrix((1, 0, 1), 50), [0, 0, 3])
    p = _plane_points(n=15, half=4.0)
    light, ctx = _load_light({"type": "point", "to_world": M.tolist(), "power": 50,
                              "color": [1, 1, 1], "ies": {"file": "lamp.ies"}}, tmp_path)
    prof = IESProfile.from_file(IES_DIR / "rab_asym360_45deg_lm02.ies")
    ls = light.sample(p, np.full((p.shape[0], 2), 0.5))
    np.testing.assert_allclose(ls.value[:, 1], _expected_irradiance_weight(prof, M, 50, p), rtol=1e-9)
    # Light selection must use the real emitted power P × flux / 177.83 (issue 4), which exceeds
    # P for any beam: a point light must not clamp its mean directional factor at 1 (use
    # IESEmission.mean_factor).
    assert light.power() == pytest.approx(50 * prof.flux / EFFICACY, rel=1e-6), type(light)
    assert ctx.warnings == []

    raw = (IES_DIR / "erco_defined_spot_lm95.ies").read_bytes()
    text = raw.decode("latin-1")
    spot, ctx = _load_light({"type": "spot", "to_world": M.tolist(), "power": 5, "spot_size": 40,
                             "spot_blend": 0.1, "ies": {"data": text}}, tmp_path)
    sprof = IESProfile.from_text(raw)
    ls = spot.sample(p, np.full((p.shape[0], 2), 0.5))
    want = _expected_irradiance_weight(sprof, M, 5, p, spot=(40, 0.1))
    np.testing.assert_allclose(ls.value[:, 1], want, rtol=1e-9, atol=1e-12 * want.max())
    assert np.count_nonzero(want) > 5


def test_ies_emission_factor():
    """The factor a point light multiplies its isotropic intensity P/(4π) by."""
    from backend.ies.light import IESEmission
    prof = IESProfile.from_file(IES_DIR / "hew_overhead_quad90_8lamps_lm95.ies")
    em = IESEmission(prof)
    d = np.array([[0, 0, -1.0], [0.6, 0, -0.8]])
    np.testing.assert_allclose(10 / (4 * np.pi) * em(d), 10 * prof.intensity(d) / EFFICACY, rtol=1e-12)
    # mean over the sphere = flux / 177.83 lm (≈ 208 here: a beam concentrates, no clamp at 1)
    assert em.mean_factor() == pytest.approx(prof.flux / EFFICACY, rel=1e-12) and em.mean_factor() > 100
    R = rotation_matrix((1, 0, 0), 30.0)
    scaled = ies_light(prof, _to_world(R, [0, 0, 2], scale=(2.0, 0.5, 1.0)), 1.0)
    assert em.mean_factor(R @ np.diag([2.0, 0.5, 1.0])) == pytest.approx(scaled.power(), rel=1e-12)


def test_scene_errors(tmp_path):
    M = np.eye(4).tolist()
    with pytest.raises(SceneError, match=r"lights\[0\]\.ies\.file: IES file not found"):
        _load_light({"type": "point", "to_world": M, "power": 1, "ies": {"file": "missing.ies"}}, tmp_path)
    with pytest.raises(SceneError, match="exactly one of"):
        _load_light({"type": "point", "to_world": M, "power": 1, "ies": {"file": "a", "data": "b"}}, tmp_path)
    bad = "IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 3 1 1 2 0 0 0\n1 1 1\n0 45 90\n0\n10 x 0\n"
    with pytest.raises(SceneError) as info:
        _load_light({"type": "spot", "to_world": M, "power": 1, "ies": {"data": bad}}, tmp_path)
    assert str(info.value) == ("scene.json: lights[0].ies.data: line 7: expected candela value 2 of 3 "
                               "(1 horizontal × 3 vertical angles): a number, got 'x'")
    (tmp_path / "bad.ies").write_text(bad)
    with pytest.raises(SceneError, match=r"lights\[0\]\.ies\.file: .*bad\.ies: line 7: expected candela"):
        _load_light({"type": "point", "to_world": M, "power": 1, "ies": {"file": "bad.ies"}}, tmp_path)
    with pytest.raises(SceneError, match=r"lights\[0\]\.ies\.strength: unknown field"):
        _load_light({"type": "point", "to_world": M, "power": 1,
                     "ies": {"data": bad.replace(" x ", " 5 "), "strength": 2}}, tmp_path)
