"""The backend also runs on numpy 2.x (a standalone user may have it; Blender bundles 1.26).

Creates ``.venv-numpy2`` once (numpy 2, embreex, OpenImageIO from requirements.txt's pins) and renders a
small scene with both environments; the images agree within Monte Carlo noise.
"""
import json
import os
import subprocess
import sys
import venv
from pathlib import Path

import numpy as np
import pytest

from backend.imageio import read_exr
from conftest import ROOT
from render_util import front_perspective, scene

VENV = ROOT / ".venv-numpy2"


def numpy2_python() -> Path:
    py = VENV / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    stamp = VENV / ".ready"
    if not stamp.exists():
        venv.EnvBuilder(with_pip=True, clear=True).create(VENV)
        pins = [line.strip() for line in (ROOT / "requirements.txt").read_text().splitlines()
                if line.strip() and not line.startswith("#") and not line.startswith("numpy")
                and not line.startswith("matplotlib")]
        subprocess.check_call([str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check",
                               "numpy>=2,<3", *pins])
        stamp.write_text("ok\n")
    return py


@pytest.mark.slow
def test_backend_renders_under_numpy2(tmp_path):
    try:
        py = numpy2_python()
    except (subprocess.CalledProcessError, OSError) as exc:
        pytest.fail(f"could not create the numpy 2 environment: {exc}")
    version = subprocess.run([str(py), "-c", "import numpy; print(numpy.__version__)"],
                             capture_output=True, text=True, check=True).stdout.strip()
    assert version.startswith("2.")
    data = scene(24, 24, front_perspective(4.0, 0.3),
                 {"m": {"type": "diffuse", "color": {"texture": "tex.png"}},
                  "gold": {"type": "conductor", "metal": "Au", "roughness": 0.2}},
                 {"ball": {"shape": "sphere", "radius": 1.0, "segments": 32},
                  "floor": {"shape": "rectangle", "size": [6, 6]}},
                 [{"mesh": "ball", "materials": ["gold"]},
                  {"mesh": "floor", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -1], [0, 0, 0, 1]],
                   "materials": ["m"]}],
                 lights=[{"type": "point", "to_world": [[1, 0, 0, 1], [0, 1, 0, -2], [0, 0, 1, 3], [0, 0, 0, 1]],
                          "power": 200.0, "color": [1, 1, 1]}],
                 world={"type": "constant", "color": [0.2, 0.2, 0.2], "strength": 1.0},
                 render={"spp": 64, "max_bounces": 3, "seed": 5})
    from backend.imageio import write_preview
    write_preview(tmp_path / "tex.png", np.random.default_rng(0).random((8, 8, 3)))
    (tmp_path / "scene.json").write_text(json.dumps(data))
    images, names = [], []
    for python, name in ((sys.executable, "np1.exr"), (str(py), "np2.exr")):
        proc = subprocess.run([python, "-m", "backend", "render", str(tmp_path / "scene.json"), "-o",
                               str(tmp_path / name), "--workers", "1"], cwd=ROOT, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        pixels, names = read_exr(tmp_path / name)
        images.append(pixels)
    a, b = images
    assert np.all(np.isfinite(b))
    # Same seed and code: the results agree up to float rounding differences between numpy versions
    # (which can flip a rare roulette decision), far inside the Monte Carlo error of the image.
    rgb_a, rgb_b = a[:, :, :3], b[:, :, :3]
    var = a[:, :, [names.index(f"variance.{c}") for c in "RGB"]]
    se_image_mean = np.sqrt(var.sum()) / var.size
    assert abs(rgb_a.mean() - rgb_b.mean()) <= 4 * se_image_mean + 1e-7
