"""Camera parity: points project to the same pixels in Blender and through the exported camera.

Blender's side uses its projection matrix (``calc_matrix_camera``, C code). Lamina's side is an
independent projection of the exported image-plane frame written here, and the backend's own
camera (its primary rays through those pixels must pass through the points)."""
from __future__ import annotations

import numpy as np
import pytest

from bpy_harness import requires_bpy, result_of, run_cases

pytestmark = [pytest.mark.blender, requires_bpy]

CONFIGS = [
    {"type": "PERSP", "res": [64, 48], "fit": "AUTO"},
    {"type": "PERSP", "res": [48, 64], "fit": "AUTO"},
    {"type": "PERSP", "res": [64, 48], "fit": "HORIZONTAL", "shift": [0.1, -0.05]},
    {"type": "PERSP", "res": [48, 64], "fit": "HORIZONTAL"},
    {"type": "PERSP", "res": [64, 48], "fit": "VERTICAL", "shift": [-0.2, 0.15]},
    {"type": "PERSP", "res": [48, 64], "fit": "VERTICAL", "shift": [0.05, 0.3]},
    {"type": "PERSP", "res": [64, 48], "fit": "AUTO", "shift": [0.25, 0.1], "pixel_aspect": [2.0, 1.0]},
    {"type": "ORTHO", "res": [64, 48], "fit": "AUTO", "shift": [0.1, 0.2]},
    {"type": "ORTHO", "res": [48, 64], "fit": "VERTICAL"},
]


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    r = run_cases("camera_cases", ["projections"], tmp=tmp_path_factory.mktemp("camera"),
                  args={"projections": {"configs": CONFIGS}})
    return result_of(r, "projections")


def project_with_frame(camera: dict, points: np.ndarray, size) -> np.ndarray:
    """Pixel coordinates of world points through the exported frame (film: x right, y down)."""
    m = np.array(camera["to_world"])
    tr, br, bl, tl = np.array(camera["frame"])
    local = (points - m[:3, 3]) @ m[:3, :3]          # to_world is a rotation + translation
    if camera["type"] == "perspective":
        z_plane = tl[2]
        hit = local * (z_plane / local[:, 2:3])      # intersection with the frame's plane
    else:
        hit = local.copy()
        hit[:, 2] = tl[2]
    u_axis, v_axis = tr - tl, bl - tl
    rel = hit - tl
    s = rel @ u_axis / (u_axis @ u_axis)
    t = rel @ v_axis / (v_axis @ v_axis)
    return np.stack([s * size[0], t * size[1]], axis=1)


@pytest.mark.parametrize("index", range(len(CONFIGS)))
def test_projection_matches_blender(cases, index):
    case = cases[index]
    points = np.array(case["points"])
    want = np.array(case["pixels"])
    got = project_with_frame(case["camera"], points, case["size"])
    # Float32 matrices in Blender: agreement to a thousandth of a pixel.
    np.testing.assert_allclose(got, want, atol=2e-3, err_msg=str(case["config"]))


@pytest.mark.parametrize("index", range(len(CONFIGS)))
def test_backend_rays_pass_through_points(cases, index):
    from backend.camera import parse_camera
    from backend.scene.reader import LoadContext, Node
    case = cases[index]
    cam = parse_camera(Node(case["camera"], "camera", LoadContext("test")))
    w, h = case["size"]
    st = np.array(case["pixels"]) / np.array([w, h])
    o, d, _, _ = cam.generate_rays(st)
    p = np.array(case["points"])
    # Distance from each point to its ray, relative to the distance along the ray.
    v = p - o
    along = np.einsum("ij,ij->i", v, d)
    miss = np.linalg.norm(v - along[:, None] * d, axis=1)
    assert np.all(miss <= 1e-4 * np.maximum(np.abs(along), 1.0)), str(case["config"])
