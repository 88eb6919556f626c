"""F12 and material previews through the warm render server (addon/engine/render_server.py):
the same pixels as a new renderer process, one process for many renders, Esc keeps it."""
from __future__ import annotations

import pytest

from bpy_harness import backend_renders, requires_bpy, result_of, run_cases

pytestmark = [pytest.mark.blender, requires_bpy,
              pytest.mark.skipif(not backend_renders(("diffuse", "layered"), ("sun",), ("constant",)),
                                 reason="the backend cannot render the scene yet")]


def test_warm_f12_matches_a_new_process_and_survives_esc(tmp_path):
    r = run_cases("f12_cases", ["warm_same_as_cold", "warm_cancel", "previews"], tmp=tmp_path, timeout=600)
    same = result_of(r, "warm_same_as_cold")
    # Two F12s in the one server process, the same pixels as a render in a process of its own.
    assert same["pid1"] is not None and same["pid1"] == same["pid2"]
    assert same["warm_equal"] and same["cold_equal"] and same["mean"] > 0.05
    esc = result_of(r, "warm_cancel")
    assert esc["error"] is None                 # a cancelled F12 is not a failure
    assert esc["pid_after_cancel"] is not None and esc["pid_next"] == esc["pid_after_cancel"]
    assert esc["next_mean"] > 0.05
    print(f"\nEsc after 0.7 s: F12 returned after {esc['seconds']:.2f} s; the next F12 "
          f"(same server) took {esc['next_seconds']:.2f} s")
    pv = result_of(r, "previews")
    assert pv["server_jobs"] == 3               # three thumbnails, one preview server
    for p in pv["previews"]:
        assert p["size"] == [128, 128] and p["first_pixels"] is not None and p["mean"] > 0.02
    print("previews, seconds to first pixels: " + ", ".join(f"{p['first_pixels']:.2f}" for p in pv["previews"]))
