"""Rendered shading (addon/engine/viewport.py) in headless Blender, against the real session.

Headless Blender has no 3D view and cannot draw: the cases (cases/viewport_cases.py) call the
engine's view_update/view_draw with a stand-in engine and region, run the add-on's timer by hand
and record what would be drawn. What only a GUI shows is listed in docs/blender.md."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from bpy_harness import requires_bpy, result_of, run_cases

pytestmark = [pytest.mark.blender, requires_bpy,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc for process state")]

CASES = ["progressive", "edits", "lifecycle", "crash", "export_error", "coalesce", "samples_change", "views",
         "borders", "denoise"]


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    return run_cases("viewport_cases", CASES, tmp=tmp_path_factory.mktemp("viewport"), timeout=900)


def test_progressive_frames_up_to_the_viewport_samples_then_idle(results):
    r = result_of(results, "progressive")
    uploads = [e for e in r["log"] if e[0] == "upload"]
    draws = [e for e in r["log"] if e[0] == "draw"]
    assert uploads and draws and uploads[-1][4] == 4               # Viewport Samples = 4
    assert all(d[5:] == [32, 24] for d in draws)                   # drawn over the whole region
    assert r["stats"][-1] == "Lamina | Sample 4/4 | Done"
    assert r["idle_cpu"] < 0.05                                    # 1 s idle: < 5 % CPU
    assert r["bound"] == 0 and r["gone"]


def test_each_edit_sends_its_sections_and_rebuilds_only_those(results):
    r = result_of(results, "edits")
    steps = {s["name"]: s for s in r["steps"]}
    expected = {
        "transform": ([["objects"]], {"soup", "bvh", "tables"}),
        "material": ([["materials"]], {"materials", "tables"}),
        "stack": ([["materials"]], {"materials", "tables"}),
        "light": ([["lights"]], {"lights", "tables"}),
        "world": ([["world"]], {"world", "tables"}),
        "add": ([["meshes", "objects"]], {"meshes", "soup", "bvh", "tables"}),
        "remove": ([["meshes", "objects"]], {"meshes", "soup", "bvh", "tables"}),
        "view": ([["camera"]], {"camera"}),
        "resize": ([["camera", "film"]], {"camera", "film"}),
        "settings": ([["render"]], {"settings", "tables"}),
    }
    assert set(steps) == set(expected)
    generations = [s["generation"] for s in r["steps"]]
    assert generations == list(range(2, 2 + len(generations)))    # one generation per edit
    for name, (sent, rebuilt) in expected.items():
        s = steps[name]
        assert s["sent"] == sent, name
        assert set(s["rebuilt"]) == rebuilt, name
        assert s["stale_draws"] == [], name            # nothing older drawn once the edit was sent
        assert s["spp"] and s["spp"][-1] == 2, name    # accumulated again up to Viewport Samples
    assert r["gone"]


def test_every_way_out_stops_the_session(results):
    r = result_of(results, "lifecycle")
    assert r == {"engine_dropped": True, "engine_del": True, "del_twice": True, "load_pre": True,
                 "sessions_after_load": 0, "unregister": True, "timer_after_unregister": False, "atexit": True}


def test_a_crashed_session_is_one_line_in_the_header_and_the_console(results):
    r = result_of(results, "crash")
    message = "the viewport renderer process ended unexpectedly (signal 9)"
    assert r["status"] == f"Lamina | Viewport renderer failed: {message}"
    assert r["console"] == f"Lamina viewport: {message}\n"        # once, no traceback


def test_an_export_error_is_shown_not_raised(results):
    r = result_of(results, "export_error")
    assert r["status"] == "Lamina | Error: material 'Ball': the layer stack is empty (add a layer or apply a preset)"
    assert "Traceback" not in r["console"] and r["console"].count("\n") == 1
    assert r["after"] == "Lamina | Sample 2/2 | Done" and not r["new_generation"]
    # present when entering Rendered mode: shown, nothing sent; fixed: the scene renders
    assert r["entering_status"] == r["status"] and r["entering_scene_sent"] is False
    assert r["fixed_status"] == "Lamina | Sample 2/2 | Done" and r["fixed_frames"] > 0


def test_edits_wait_for_the_previous_image_and_go_out_together(results):
    r = result_of(results, "coalesce")
    assert r["sent_before"] == [["lights"]] and r["waiting"] == ["lights", "objects"]
    assert r["sent"] == [["lights"], ["lights", "objects"]] and r["lights"] == 700.0


def test_more_viewport_samples_continue_without_restarting(results):
    r = result_of(results, "samples_change")
    assert r["generation_before"] == r["generation_after"] == 1
    assert r["spp"][0] == 2 and r["spp"][-1] == 5
    assert r["generation_after_final_settings"] == r["generation_before"]


def _rays(camera, st):
    """World-space ray lines (origin, unit direction) of a scene-file camera at film positions."""
    m = np.array(camera["to_world"])
    tr, br, bl, tl = (np.array(c) for c in camera["frame"])
    out = []
    for s, t in st:
        p = tl + s * (tr - tl) + t * (bl - tl)
        if camera["type"] == "perspective":
            o, d = np.zeros(3), p / np.linalg.norm(p)
        else:
            o, d = np.array([p[0], p[1], 0.0]), np.array([0.0, 0.0, -1.0])
        o = m[:3, :3] @ o + m[:3, 3]
        d = m[:3, :3] @ d
        out.append((o, d / np.linalg.norm(d)))
    return out


def test_viewport_camera_rays_equal_the_exported_camera(results):
    """Camera view: the rays from the region's matrices are the scene camera's rays (shift,
    sensor fit, orthographic) — the same lines, for every film position."""
    st = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.3, 0.7), (0.5, 0.5)]
    for case in result_of(results, "views"):
        a, b = _rays(case["exported"], st), _rays(case["viewport"], st)
        assert case["viewport"]["type"] == case["exported"]["type"]
        for (oa, da), (ob, db) in zip(a, b):
            np.testing.assert_allclose(db, da, atol=1e-5, err_msg=str(case["fit"]))
            gap = ob - oa                                    # same line: the offset runs along it
            np.testing.assert_allclose(gap - np.dot(gap, da) * da, 0, atol=1e-5, err_msg=str(case))


def test_render_borders_crop_and_pixel_size(results):
    r = result_of(results, "borders")
    cam = r["camera"]          # border x 0.25–0.75, y 0–0.5 of the camera frame (= the region here)
    assert cam["crop"] == [8, 12, 24, 24]
    assert cam["alpha_rows"] == [0] * 12 + [16] * 12 and cam["alpha_cols"] == [0] * 8 + [12] * 16 + [0] * 8
    region = r["region"]       # View Region border: the top-right quarter
    assert region["crop"] == [16, 0, 32, 12]
    assert region["alpha_rows"] == [16] * 12 + [0] * 12
    assert r["pixel_size_2"] == [16, 12, 32, 24]         # half resolution, drawn over the region


def test_denoise_viewport_draws_the_final_frame_denoised(results):
    r = result_of(results, "denoise")
    assert r["features"] and r["finite"] and r["same_frame"]
    assert r["noisy_first_equal"]                  # drawn as rendered first, then denoised
    assert r["status_on"] == "Lamina | Sample 4/4 | Done, denoised"
    assert r["status_off"] == "Lamina | Sample 4/4 | Done"
    assert not any(r["earlier_final"])             # only the final frame is denoised
    # OIDN takes the 4-spp image closer to the converged one (1024 spp, the same session).
    print(f"\nviewport 96×72, 4 spp: albedo {r['albedo_mean']}, normal z {r['normal_z_mean']:.3f}; RMSE against 1024 spp noisy {r['noisy_rmse']:.4f}, denoised "
          f"{r['denoised_rmse']:.4f}; neighbour differences {r['noisy_roughness']:.4f} -> {r['denoised_roughness']:.4f}")
    assert r["denoised_rmse"] < 0.8 * r["noisy_rmse"], r
    assert r["denoised_roughness"] < r["noisy_roughness"], r
    assert abs(r["denoised_mean"] / r["noisy_mean"] - 1.0) < 0.1, r
