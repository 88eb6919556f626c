"""Render › Denoise with the Open Image Denoise that Blender ships (addon/engine/denoise.py): the
Combined pass of an F12 render is denoised, closer to a converged render than the render itself,
and the render as rendered is the Noisy Image pass."""
from __future__ import annotations

import numpy as np
import pytest

from bpy_harness import backend_renders, requires_bpy, result_of, run_cases
from test_engine import channels_named, read_exr_parts

pytestmark = [pytest.mark.blender, requires_bpy,
              pytest.mark.skipif(not backend_renders(("diffuse",), ("area",), ("constant",)),
                                 reason="needs the renderer")]


def test_f12_denoises_combined_and_keeps_the_noisy_image(tmp_path):
    r = run_cases("denoise_cases", ["renders"], tmp=tmp_path)
    case = result_of(r, "renders")
    assert case["denoised_error"] is None and case["plain_error"] is None and case["reference_error"] is None
    denoised_parts = read_exr_parts(case["denoised"])
    denoised = channels_named(denoised_parts, ["Combined.R", "Combined.G", "Combined.B"])
    noisy = channels_named(denoised_parts, ["Noisy Image.R", "Noisy Image.G", "Noisy Image.B"])
    plain = channels_named(read_exr_parts(case["plain"]), ["Combined.R", "Combined.G", "Combined.B"])
    reference = channels_named(read_exr_parts(case["reference"]), ["Combined.R", "Combined.G", "Combined.B"])
    # The Noisy Image pass is the render itself: the same seed and samples without Denoise.
    assert np.array_equal(noisy, plain)
    # The reference (1024 spp, another seed) has 1/256 of the 4-spp variance: it adds a little to
    # both errors' squares alike, so the ratio below understates the denoiser's gain.
    rmse = lambda image: float(np.sqrt(np.mean((image - reference) ** 2)))
    print(f"\nF12 at 4 spp: RMSE noisy {rmse(noisy):.4f}, denoised {rmse(denoised):.4f} "
          f"({rmse(denoised) / rmse(noisy):.2f}x)")
    assert rmse(denoised) <= 0.5 * rmse(noisy)
    assert abs(denoised.mean() / reference.mean() - 1) < 0.03
    output = r["_stdout"] + r["_stderr"]
    assert "Lamina: denoised in " in output and "not denoised" not in output, output[-2000:]
