"""``render --denoise`` (backend/denoise.py): the image OIDN makes from a noisy render, fed with the
film's albedo and normal, is closer to the converged image than the render itself; the EXR keeps
the render as its ``noisy`` layer; without the optional denoiser one line says so and the image is
written as rendered."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from backend.imageio import read_exr
from conftest import ROOT
from render_util import render, scene

pyoidn = pytest.importorskip("pyoidn", reason="the optional denoiser (requirements-denoise.txt)")


def room(spp: int, seed: int = 1) -> dict:
    """A floor, a box and a wall under a small area light: edges, a shadow, indirect light."""
    eye = {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0.6, -0.8, -4], [0, 0.8, 0.6, 3.2], [0, 0, 0, 1]],
           "frame": [[0.5, 0.375, -1], [0.5, -0.375, -1], [-0.5, -0.375, -1], [-0.5, 0.375, -1]]}
    floor = {"positions": [[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], "indices": [[0, 1, 2], [0, 2, 3]]}
    wall = {"positions": [[-3, 1.5, 0], [3, 1.5, 0], [3, 1.5, 3], [-3, 1.5, 3]], "indices": [[0, 1, 2], [0, 2, 3]]}
    box = {"positions": [[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0],
                         [-0.5, -0.5, 1], [0.5, -0.5, 1], [0.5, 0.5, 1], [-0.5, 0.5, 1]],
           "indices": [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                       [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]}
    light = {"type": "area", "shape": "square", "size": 0.6, "power": 300.0,
             "to_world": [[1, 0, 0, 1.0], [0, 1, 0, -0.8], [0, 0, 1, 3.0], [0, 0, 0, 1]]}
    return scene(64, 48, eye, {"grey": {"type": "diffuse", "color": 0.6}, "red": {"type": "diffuse", "color": [0.7, 0.15, 0.1]}},
                 {"floor": floor, "wall": wall, "box": box},
                 [{"mesh": "floor", "materials": ["grey"]}, {"mesh": "wall", "materials": ["grey"]},
                  {"mesh": "box", "materials": ["red"]}],
                 lights=[light], world={"type": "constant", "color": [0.05, 0.05, 0.05]},
                 render={"spp": spp, "max_bounces": 4, "seed": seed})


def _cli(tmp_path, data, *extra, env=None):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(data))
    out = tmp_path / f"out{len(list(tmp_path.glob('out*.exr')))}.exr"
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(path), "-o", str(out),
                           "--workers", "2", *extra], cwd=ROOT, capture_output=True, text=True,
                          timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr
    pixels, names = read_exr(out)
    return proc, pixels, names


def _rgb(pixels, names, layer=""):
    prefix = f"{layer}." if layer else ""
    return pixels[:, :, [names.index(f"{prefix}{c}") for c in "RGB"]]


def test_denoised_image_is_closer_to_the_converged_one(tmp_path):
    reference = render(room(1024, seed=7), workers=2).film.combined()[:, :, :3]
    _, plain, plain_names = _cli(tmp_path, room(4))
    proc, pixels, names = _cli(tmp_path, room(4), "--denoise")
    noisy, denoised = _rgb(pixels, names, "noisy"), _rgb(pixels, names)
    # The noisy layer is the render itself (same seed and spp, bit for bit).
    assert np.array_equal(noisy, _rgb(plain, plain_names))
    assert not np.array_equal(noisy, denoised) and np.all(np.isfinite(denoised))
    # Error against a 1024-spp render; that reference's own noise (1/16 of the 4-spp variance)
    # adds to both errors alike, so the measured ratio understates the gain.
    rmse = lambda image: float(np.sqrt(np.mean((image - reference) ** 2)))
    print(f"\n4 spp RMSE: noisy {rmse(noisy):.4f}, denoised {rmse(denoised):.4f} "
          f"({rmse(denoised) / rmse(noisy):.2f}x)")
    assert rmse(denoised) <= 0.5 * rmse(noisy)
    # The mean brightness survives denoising (no energy lost or made), within 2 %.
    assert abs(denoised.mean() / reference.mean() - 1) < 0.02


def test_without_the_denoiser_one_line_says_so_and_the_render_is_written(tmp_path):
    import os
    shim = tmp_path / "shim"
    shim.mkdir()
    (shim / "pyoidn.py").write_text("raise ImportError('no pyoidn wheel for this platform (test)')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(shim), str(ROOT)]))
    proc, pixels, names = _cli(tmp_path, room(2), "--denoise", env=env)
    lines = [l for l in proc.stderr.splitlines() if "--denoise" in l]
    assert len(lines) == 1 and "pip install pyoidn" in lines[0] and "without denoising" in lines[0], proc.stderr
    assert "noisy.R" not in names and "Traceback" not in proc.stderr
