"""Mesh loading and the embree scene: the fast paths agree with the straightforward ones."""
import json

import numpy as np
import pytest

from backend.geometry.embree_fill import triangle_scene
from backend.kernels.soup import nondegenerate


def _soup(rng, count):
    centres = rng.uniform(-1, 1, (count, 1, 3))
    return (centres + rng.normal(0, 0.03, (count, 3, 3))).astype(np.float32)


def test_embree_scene_filled_by_numpy_gives_the_hits_of_embreex_triangle_mesh():
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh
    rng = np.random.default_rng(3)
    v = _soup(rng, 20000)
    fast = triangle_scene(v)
    # The pinned embreex on this platform must take the fast route (else 1 M triangles cost 2.7 s).
    assert fast is not None
    slow = rtcs.EmbreeScene()
    TriangleMesh(slow, v)
    o = rng.uniform(-2, 2, (50000, 3)).astype(np.float32)
    d = rng.normal(size=(50000, 3)).astype(np.float32)
    a, b = fast.run(o, d, output=True), slow.run(o, d, output=True)
    assert (a["primID"] >= 0).mean() > 0.1
    for key in ("primID", "geomID", "tfar", "u", "v"):
        assert np.array_equal(a[key], b[key]), key
    tmax = rng.uniform(0, 3, 50000).astype(np.float32)
    occ_a = fast.run(o, d, dists=tmax.copy(), query="OCCLUDED")
    occ_b = slow.run(o, d, dists=tmax.copy(), query="OCCLUDED")
    assert np.array_equal(occ_a, occ_b)


def test_embree_scene_of_no_triangles_misses_everything():
    scene = triangle_scene(np.zeros((0, 3, 3), np.float32))
    assert scene is not None
    hits = scene.run(np.zeros((4, 3), np.float32), np.ones((4, 3), np.float32), output=True)
    assert np.all(hits["primID"] == -1)


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
