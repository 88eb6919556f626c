"""Mesh loading and the embree scene: the fast paths agree with the straightforward ones."""
import json
from pathlib import Path

import numpy as np
import pytest

from backend.kernels.soup import nondegenerate


def _soup(rng, count):
    centres = rng.uniform(-1, 1, (count, 1, 3))
    return (centres + rng.normal(0, 0.03, (count, 3, 3))).astype(np.float32)


def test_compiled_queries_on_the_numpy_filled_scene_give_embreex_answers():
    """The scene filled by NumPy (geometry/embree_lib.py) queried by the compiled loops
    (kernels/trace.py) answers as embreex's TriangleMesh queried by embreex's run: same triangle,
    distance and barycentrics, same occlusion."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    from backend.geometry.accel import EmbreeQueries
    rng = np.random.default_rng(3)
    v = _soup(rng, 20000)
    fast = EmbreeQueries(v)
    # The pinned embreex on this platform must take the direct route (else 1 M triangles cost
    # 2.7 s to build and rays cannot carry a time).
    assert fast.direct is not None
    slow = rtcs.EmbreeScene()
    TriangleMesh(slow, v)
    o = rng.uniform(-2, 2, (50000, 3)).astype(np.float32)
    d = rng.normal(size=(50000, 3)).astype(np.float32)
    tmax = np.where(rng.uniform(size=50000) < 0.5, 3e38, rng.uniform(0, 3, 50000)).astype(np.float32)
    prim, t, b1, b2 = fast.intersect(o, d, tmax.copy())
    ref = slow.run(o, d, dists=tmax.copy(), output=True)
    hit = ref["primID"] >= 0
    assert 0.1 < hit.mean() < 0.9
    assert np.array_equal(prim, ref["primID"])
    for mine, theirs in ((t, ref["tfar"]), (b1, ref["u"]), (b2, ref["v"])):
        assert np.array_equal(mine[hit], theirs[hit])
    assert np.array_equal(t[~hit], tmax[~hit])             # misses keep their limit
    occ = fast.occluded(o, d, tmax.copy())
    assert np.array_equal(occ, slow.run(o, d, dists=tmax.copy(), query="OCCLUDED"))
    assert 0.05 < (occ == 0).mean() < 0.95


def test_embree_scene_of_no_triangles_misses_everything():
    from backend.geometry.accel import EmbreeQueries
    q = EmbreeQueries(np.zeros((0, 3, 3), np.float32))
    assert q.direct is not None
    prim, *_ = q.intersect(np.zeros((4, 3), np.float32), np.ones((4, 3), np.float32),
                           np.full(4, 3e38, np.float32))
    assert np.all(prim == -1)


def test_degenerate_triangle_test_matches_the_float64_formula():
    rng = np.random.default_rng(5)
    pos = rng.uniform(-10, 10, (3000, 3)).astype(np.float32)
    idx = rng.integers(0, 3000, (6000, 3)).astype(np.int32)
    idx[:500, 2] = idx[:500, 1]                                  # two equal corners: zero area
    pos[2000:2100] = pos[1000:1100] * np.float32(1 + 1e-7)       # nearly coincident corners
    idx[500:600] = np.stack([np.arange(1000, 1100), np.arange(2000, 2100), np.arange(1100, 1200)], 1)
    p = pos.astype(np.float64)[idx]
    area2 = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    scale = np.maximum(np.abs(p).max(axis=(1, 2)), 1e-30)
    expected = area2 > scale * scale * 1e-12
    got = nondegenerate(pos, idx)
    assert not got[:500].any()
    assert got.sum() > 5000
    assert np.array_equal(got, expected)


@pytest.mark.parametrize("per_vertex", [True, False])
def test_a_nan_normal_names_a_triangle_that_uses_it(tmp_path, per_vertex):
    from backend.errors import SceneError
    from backend.scene.loader import load_scene
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [5, 5, 5]], np.float32)
    idx = np.array([[0, 1, 2], [1, 3, 2]], np.int32)
    if per_vertex:
        normals = np.tile(np.float32([0, 0, 1]), (5, 1))
        normals[4] = np.nan                   # used by no triangle: harmless
        np.savez(tmp_path / "ok.npz", positions=pos, indices=idx, normals=normals)
        normals = normals.copy()
        normals[3] = np.nan                   # only triangle 1 uses vertex 3
    else:
        normals = np.tile(np.float32([0, 0, 1]), (2, 3, 1))
        np.savez(tmp_path / "ok.npz", positions=pos, indices=idx, normals=normals)
        normals = normals.copy()
        normals[1, 2, 0] = np.nan
    np.savez(tmp_path / "bad.npz", positions=pos, indices=idx, normals=normals)

    def scene(mesh):
        path = tmp_path / f"{mesh}.json"
        path.write_text(json.dumps({
            "format": "lamina-scene", "version": 1, "film": {"width": 4, "height": 4},
            "camera": {"type": "perspective", "to_world": np.eye(4).tolist(),
                       "frame": [[0.4, 0.4, -1], [0.4, -0.4, -1], [-0.4, -0.4, -1], [-0.4, 0.4, -1]]},
            "materials": {"m": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}},
            "meshes": {"tri": {"file": f"{mesh}.npz"}},
            "objects": [{"mesh": "tri", "materials": ["m"]}]}))
        return path

    assert load_scene(scene("ok")).soup.count == 2
    with pytest.raises(SceneError) as err:
        load_scene(scene("bad"))
    assert "normals of triangle 1 is not finite" in str(err.value)


def test_direct_calls_reach_embreex_embree_even_with_another_embree_loaded(tmp_path):
    """bpy bundles its own embree: a process holding both (the Blender tests import bpy) must
    still call the library embreex's scene belongs to (the other one deadlocked in its task
    scheduler when it committed embreex's scene). In a fresh process: load bpy's embree first,
    then check where the functions resolve and that a scene commits and traces."""
    import importlib.util
    import subprocess
    import sys
    spec = importlib.util.find_spec("bpy")
    others = sorted((Path(spec.origin).parent / "lib").glob("libembree4*")) if spec and spec.origin else []
    if not others:
        pytest.skip("no second embree library (bpy) on this machine")
    code = f"""
import ctypes, numpy as np
ctypes.CDLL({str(others[0])!r})
from backend.geometry.embree_lib import _embree
from backend.geometry.accel import EmbreeQueries
addr = ctypes.cast(_embree().rtcCommitScene, ctypes.c_void_p).value
owner = [l.split()[-1] for l in open('/proc/self/maps')
         if int(l.split('-')[0], 16) <= addr < int(l.split()[0].split('-')[1], 16)]
q = EmbreeQueries(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32))
prim, *_ = q.intersect(np.array([[0.2, 0.2, 1]], np.float32), np.array([[0, 0, -1]], np.float32),
                       np.full(1, 3e38, np.float32))
print(owner[0], int(prim[0]))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         cwd=Path(__file__).resolve().parent.parent)
    assert out.returncode == 0, out.stderr[-2000:]
    owner, prim = out.stdout.split()
    assert "embreex" in owner and "bpy" not in owner, owner
    assert prim == "0"


def test_placed_normals_and_scene_bounds_match_their_closed_forms():
    """Per-vertex normals placed by a sheared, mirroring matrix are the float64 normal-matrix
    product renormalised, rounded once to float32 (each triangle's corners swapped by the mirror),
    and the scene's centre and radius come from the extremes of every placed corner (the loader
    computes both with faster NumPy paths than these)."""
    from backend.scene.loader import load_scene_data
    rng = np.random.default_rng(7)
    pos = rng.uniform(-1, 1, (40, 3))
    idx = np.array([rng.choice(40, 3, replace=False) for _ in range(60)])
    nrm = rng.normal(size=(40, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    m = np.array([[1.5, 0.4, 0.0, 0.3], [0.0, -0.8, 0.2, -1.0], [0.1, 0.0, 2.0, 0.5], [0, 0, 0, 1]])
    cam = {"type": "perspective", "to_world": np.eye(4).tolist(),
           "frame": [[0.5, 0.5, -1], [0.5, -0.5, -1], [-0.5, -0.5, -1], [-0.5, 0.5, -1]]}
    data = {"format": "lamina-scene", "version": 1, "film": {"width": 4, "height": 4}, "camera": cam,
            "materials": {"m": {"type": "diffuse", "color": 0.5}},
            "meshes": {"a": {"positions": pos.tolist(), "indices": idx.tolist(), "normals": nrm.tolist()}},
            "objects": [{"mesh": "a", "materials": ["m"], "to_world": m.tolist()}]}
    scene = load_scene_data(data, "<test>")
    assert np.linalg.det(m[:3, :3]) < 0
    order = [0, 2, 1]                                  # the mirror swaps two corners
    n_ref = nrm.astype(np.float32).astype(np.float64)[idx][:, order] @ np.linalg.inv(m[:3, :3])
    n_ref /= np.linalg.norm(n_ref, axis=2, keepdims=True)
    np.testing.assert_array_equal(scene.soup.normals, n_ref.astype(np.float32))
    corners = (pos.astype(np.float32).astype(np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32)[idx][:, order]
    np.testing.assert_array_equal(scene.soup.vertices, corners)
    pts = np.concatenate([corners.reshape(-1, 3).astype(np.float64), np.zeros((1, 3))])   # + the camera
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    np.testing.assert_allclose(scene.center, 0.5 * (lo + hi), rtol=0, atol=1e-12)
    assert scene.radius == pytest.approx(0.5 * np.linalg.norm(hi - lo), rel=1e-12)
