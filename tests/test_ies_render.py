"""End-to-end: a diffuse plane under a rotated IES light, rendered with the path tracer, against the
analytic radiance ρ/π · I(θ, φ) cosθ / r² from the table (same interpolation), within 4σ per
region, for files of different symmetry (asymmetric, bilateral, quadrilateral, type B)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("backend.render")

from backend.ies.profile import IESProfile
from ies_reference import rotation_matrix
from render_util import region_means, render, scene

IES_DIR = Path(__file__).parent / "data" / "ies"
K_SIGMA = 4.0
EFFICACY = 177.83


def _ortho_down(half, height=5.0):
    h = half
    return {"type": "orthographic", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, height], [0, 0, 0, 1]],
            "frame": [[h, h, -1], [h, -h, -1], [-h, -h, -1], [-h, h, -1]]}


@pytest.mark.parametrize("name,axis,angle", [
    ("rab_asym360_45deg_lm02.ies", (0.3, 0.2, 1.0), 35.0),            # no symmetry (0..360)
    ("qssi_roadway_typeIII_bilateral180_lm95.ies", (0.0, 0.3, 1.0), -60.0),   # bilateral
    ("hew_overhead_quad90_8lamps_lm95.ies", (1.0, 0.0, 0.4), 25.0),   # quadrilateral
    ("rab_ffled_flood_typeB_lm02.ies", (0.0, 1.0, 0.0), -70.0),       # type B, beam turned down
])
def test_rendered_plane_matches_analytic_irradiance(name, axis, angle):
    size, half, rho, P, height = 32, 2.5, 0.6, 20.0, 1.2
    R = rotation_matrix(axis, angle)
    pos = np.array([0.2, -0.3, height])
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, pos
    light = {"type": "point", "to_world": M.tolist(), "power": P, "color": [1, 1, 1],
             "ies": {"file": str(IES_DIR / name)}}
    data = scene(size, size, _ortho_down(half),
                 {"plane": {"type": "diffuse", "color": rho}},
                 {"plane": {"shape": "rectangle", "size": [2 * half + 1, 2 * half + 1]}},
                 [{"mesh": "plane", "materials": ["plane"]}], lights=[light],
                 render={"spp": 16, "max_bounces": 0, "seed": 11},
                 film_filter={"type": "box", "width": 1.0})
    result = render(data)
    img = result.film.combined()[:, :, 1]
    var = result.film.variance_of_mean()[:, :, 1]

    # Analytic pixel values: mean of ρ/π · E over an 8×8 grid in each pixel's footprint.
    prof = IESProfile.from_file(IES_DIR / name)
    sub = 8
    t = ((np.arange(size)[:, None] + (np.arange(sub) + 0.5)[None, :] / sub) / size).ravel()
    x = -half + 2 * half * t                   # columns, left → right = −X → +X
    y = half - 2 * half * t                    # rows, top → bottom = +Y → −Y
    X, Y = np.meshgrid(x, y)
    p = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    d = p - pos
    r2 = np.einsum("ij,ij->i", d, d)
    cd = prof.intensity(d @ R)                 # R^T d: direction in the light's frame
    E = P * cd / EFFICACY * (pos[2] / np.sqrt(r2)) / r2
    ref = (rho / np.pi * E).reshape(size, sub, size, sub).mean(axis=(1, 3))

    regions = region_means(img[..., None], var[..., None], np.ones(img.shape, bool), 4)
    lit = 0
    for by, bx, mean, se, (ys, xs) in regions:
        expected = ref[ys, xs].mean()
        assert abs(mean[0] - expected) <= K_SIGMA * se[0] + 1e-9 * expected, (by, bx, mean[0], expected, se[0])
        lit += expected > 1e-3 * ref.max()
    assert lit >= 6   # the light really falls on a good part of the plane
    # The orientation matters: the same light unrotated would give a different image.
    R0 = np.eye(3)
    cd0 = prof.intensity(d @ R0)
    E0 = P * cd0 / EFFICACY * (pos[2] / np.sqrt(r2)) / r2
    ref0 = (rho / np.pi * E0).reshape(size, sub, size, sub).mean(axis=(1, 3))
    assert np.abs(ref0 - ref).max() > 0.2 * ref.max()
