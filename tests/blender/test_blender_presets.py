"""Material presets in Blender: apply, save → load round trip, menu, user folder, exact export.

The Blender side runs in one bpy process with the add-on loaded as an extension
(tests/blender/cases/preset_cases.py); here the exported material JSON is compared field by
field and parsed with the backend's own loader (the renderer's view of the material).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bpy_harness import ROOT, requires_bpy, result_of, run_cases

pytestmark = [pytest.mark.blender, requires_bpy]

CASES = ["round_trip", "shipped", "menu", "user_folder", "dropped_fields", "user_thumbnail", "repeated_saves"]
# Blender stores the stack's numbers as float32 and writes them with 7 significant digits; α is
# stored as √α. A value therefore comes back within a few float32 ulps: 4 ulps (2^-21 relative)
# bounds rounding to float32, squaring a rounded √α and the 7-digit print.
FLOAT32_RTOL = 4 * 2.0 ** -23


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    return run_cases("preset_cases", CASES, tmp=tmp_path_factory.mktemp("presets"), dev_load="extension",
                     timeout=420)


def shipped_names() -> list[str]:
    return sorted(p.stem for p in (ROOT / "presets").glob("*.json"))


# ------------------------------------------------------------------ comparing materials

def texels(path: Path):
    from backend.textures import read_image
    pixels, _ = read_image(Path(path))
    return pixels


def json_diff(a, b, dir_a: Path | None, dir_b: Path | None, path: str = "") -> list[str]:
    """Field-by-field differences of two material JSONs; textures compare by their pixels."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{path}: keys {sorted(a)} vs {sorted(b)}"]
        if isinstance(a.get("texture"), str):
            out = [f"{path}.{k}: {a[k]!r} vs {b[k]!r}" for k in a if k != "texture" and a[k] != b[k]]
            pa, pb = Path(a["texture"]), Path(b["texture"])
            pa, pb = (pa if pa.is_absolute() else dir_a / pa), (pb if pb.is_absolute() else dir_b / pb)
            ta, tb = texels(pa), texels(pb)
            if ta.shape != tb.shape or not np.array_equal(ta, tb):
                out.append(f"{path}.texture: pixels of {pa} differ from {pb}")
            return out
        return [d for k in a for d in json_diff(a[k], b[k], dir_a, dir_b, f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} vs {len(b)} items"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in json_diff(x, y, dir_a, dir_b, f"{path}[{i}]")]
    return [] if a == b and type(a) is type(b) else [f"{path}: {a!r} vs {b!r}"]


SKIP_ATTRS = {"stats", "source"}      # run counters; a texture's file name (its texels are compared)


def object_diff(a, b, rtol: float, path: str = "value", seen=None, skip=SKIP_ATTRS) -> list[str]:
    """Differences between two parsed backend objects (materials, lights), recursively through
    their attributes; numbers within ``rtol`` (0 = exactly equal); attributes in ``skip`` ignored."""
    seen = set() if seen is None else seen
    if type(a) is not type(b):
        return [f"{path}: {type(a).__name__} vs {type(b).__name__}"]
    if isinstance(a, np.ndarray):
        if a.shape != b.shape:
            return [f"{path}: shape {a.shape} vs {b.shape}"]
        if a.dtype.kind in "fc":
            ok = np.array_equal(a, b) if rtol == 0 else np.allclose(a, b, rtol=rtol, atol=rtol)
        else:
            ok = np.array_equal(a, b)
        return [] if ok else [f"{path}: {a.ravel()[:6]} vs {b.ravel()[:6]}"]
    if isinstance(a, (bool, str, type(None), type)) or callable(a) and not hasattr(a, "__dict__"):
        return [] if a == b else [f"{path}: {a!r} vs {b!r}"]
    if isinstance(a, (int, float, np.number)):
        ok = a == b if rtol == 0 else math.isclose(float(a), float(b), rel_tol=rtol, abs_tol=rtol)
        return [] if ok else [f"{path}: {a!r} vs {b!r}"]
    if isinstance(a, dict):
        if set(a) != set(b):
            return [f"{path}: keys {sorted(map(str, a))} vs {sorted(map(str, b))}"]
        return [d for k in a if k not in skip for d in object_diff(a[k], b[k], rtol, f"{path}[{k!r}]", seen, skip)]
    if isinstance(a, (list, tuple)):
        if len(a) != len(b):
            return [f"{path}: {len(a)} vs {len(b)} items"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in object_diff(x, y, rtol, f"{path}[{i}]", seen, skip)]
    key = (id(a), id(b))
    if key in seen:
        return []
    seen.add(key)
    if hasattr(a, "__dict__"):
        return object_diff({k: v for k, v in vars(a).items() if k not in skip},
                           {k: v for k, v in vars(b).items() if k not in skip}, rtol, path, seen, skip)
    return [] if a == b else [f"{path}: {a!r} vs {b!r}"]


def parse(material: dict, where: str, base: Path):
    from backend.presets import parse_material_document
    parsed, _ = parse_material_document(material, where, base)
    return parsed


def preset_file(name: str) -> tuple[dict, Path]:
    from backend.presets import load_preset_document
    path = ROOT / "presets" / f"{name}.json"
    return load_preset_document(path)["material"], path.parent


# ------------------------------------------------------------------ tests

def test_comparison_detects_a_changed_value():
    """The comparator used below is not blind: a 1e-4 relative change of one medium parameter
    of a textured preset is found, at the float32 tolerance and exactly."""
    doc, base = preset_file("lacquered-wood")
    changed = json.loads(json.dumps(doc))
    changed["media"][0]["albedo"][1] *= 1.0001
    assert not object_diff(parse(doc, "a", base), parse(json.loads(json.dumps(doc)), "b", base), 0.0)
    assert object_diff(parse(doc, "a", base), parse(changed, "b", base), FLOAT32_RTOL)


def test_user_preset_round_trip_reproduces_the_stack(results):
    r = result_of(results, "round_trip")
    assert set(r) == {"Rich A", "Rich C", "Plain Gold"}
    for name, rec in r.items():
        assert rec["status"] == [["FINISHED"], ["FINISHED"]], name
        # The re-applied material's stack exports exactly what the original's did.
        diff = json_diff(rec["original"], rec["reapplied"], Path(rec["orig_dir"]), Path(rec["again_dir"]))
        assert not diff, (name, diff)
        # And the link writes the saved file's material exactly (textures next to the preset).
        from backend.presets import load_preset_document
        stored = load_preset_document(Path(rec["file"]))["material"]
        assert not json_diff(stored, rec["linked"], Path(rec["file"]).parent, None), name
        assert rec["state"] == "EXACT" and rec["dropped"] == [] and rec["src_state"] == "EXACT"
    rich = r["Rich A"]["original"]
    # The round trip covered what it should: textures of every kind, nesting, emission.
    text = json.dumps(rich)
    for needle in ('"masking": "separable"', '"roughness_v"', '"microflake"', '"sggx"', '"hg"', '"vmf"',
                   '"type": "null"', '"emission"', ".pfm", "thick.png", "weave.png", "density.png",
                   "tint.png", "paint.png"):
        assert needle in text, needle
    assert r["Rich A"]["original"]["media"][0]["sigma_t"] == [2.0, 1.0, 0.5]
    assert r["Rich C"]["original"]["interfaces"][1]["eta"] == [0.2, 0.9, 1.1]
    assert r["Plain Gold"]["original"]["type"] == "conductor"
    # The layers' normal and bump maps: on the interfaces of a stack, and on the material where
    # a one-interface stack is written as its interface; the backend loads both.
    coat, metal = r["Rich C"]["original"]["interfaces"]
    assert coat["normal"]["texture"].endswith("ripples.png") and coat["normal_strength"] == pytest.approx(0.6)
    assert metal["bump"]["height"]["texture"].endswith("hammered.png")
    assert (metal["bump"]["distance"], metal["bump"]["strength"], metal["bump"]["invert"]) == \
        (pytest.approx(0.02), pytest.approx(0.7), True)
    gold = r["Plain Gold"]["original"]
    assert gold["bump"]["height"]["texture"].endswith("brushed.png") and "invert" not in gold["bump"]
    rich_c = parse(r["Rich C"]["original"], "Rich C", Path(r["Rich C"]["orig_dir"]))
    assert rich_c.normals[0].normal is not None and rich_c.normals[0].strength == pytest.approx(0.6)
    assert rich_c.normals[1].bump is not None and rich_c.normals[1].bump.distance == pytest.approx(-0.02)
    assert parse(gold, "Plain Gold", Path(r["Plain Gold"]["orig_dir"])).bump.distance == pytest.approx(0.01)


def test_shipped_presets_apply_and_export_as_the_backend_loads_them(results):
    r = result_of(results, "shipped")
    assert sorted(r) == shipped_names()
    for name, rec in r.items():
        assert rec["status"] == ["FINISHED"] and rec["state"] == "EXACT", name
        doc, base = preset_file(name)
        reference = parse(doc, name, base)
        # Exported through the link: the very material of the preset file.
        assert not object_diff(reference, parse(rec["linked"], f"{name} (export)", base), 0.0), name
        # A portable export copies the preset's textures next to the scene and still loads the same.
        copied_dir = Path(rec["copied_dir"])
        assert not object_diff(reference, parse(rec["copied"], f"{name} (copied)", copied_dir), 0.0), name
        if "texture" in json.dumps(doc):
            assert "/presets/" not in json.dumps(rec["copied"]) and (copied_dir / "textures").is_dir()
        # The stack the editor shows: equal within float32 storage exactly when nothing was dropped.
        stack_diff = object_diff(reference, parse(rec["stack"], f"{name} (stack)", base), FLOAT32_RTOL)
        assert bool(stack_diff) == bool(rec["dropped"]), (name, stack_diff[:3], rec["dropped"])


def test_menu_lists_every_shipped_preset_with_its_thumbnail(results):
    from backend.textures import read_image
    r = result_of(results, "menu")
    applied = [e for e in r["entries"] if e["op"] == "lamina.preset_apply"]
    names = [e["name"] for e in applied]
    user_names = r["user_names"]                  # menu-test, and those saved by earlier cases
    assert "menu-test" in user_names and not set(user_names) & set(shipped_names())
    assert sorted(names) == sorted(shipped_names() + user_names)
    for name in shipped_names():
        thumb = ROOT / "presets" / "thumbnails" / f"{name}.png"
        assert r["thumbnails"][name] == str(thumb)
        loaded = r["loaded"][str(thumb)]                  # the menu loaded it as an icon
        assert loaded["size"] == [128, 128]
        # Independent read of the PNG: the icon shows the file's pixels (mean within 8-bit steps).
        pixels = read_image(thumb)[0][..., :3].astype(np.float64)
        assert np.allclose(loaded["mean_rgb"], pixels.reshape(-1, 3).mean(axis=0), atol=1.0 / 255), name
    for entry in applied:                       # user presets have no thumbnail: generic icon
        if entry["name"] in user_names:
            assert r["thumbnails"][entry["name"]] is None and entry["icon"] == "MATERIAL"
    assert not [p for p in r["loaded"] if "thumbnails" not in p]
    assert sorted(e["name"] for e in r["delete"]) == user_names
    assert "lamina.preset_save" in [e["op"] for e in r["entries"]]
    assert sorted(n for n, _ in r["browser"]) == sorted(shipped_names() + user_names)
    panel = r["panel"]
    assert ["menu", "LAMINA_MT_material_presets", "Presets", "PRESET"] in panel
    assert any(c[0] == "label" and c[1].startswith("Preset: Gabardine") and c[2] == "LINKED" for c in panel)
    assert any(c[:2] == ["operator", "lamina.preset_detach"] for c in panel)
    assert ["template_icon_view", "lamina_preset_browser"] in r["browser_panel"]
    assert ["operator", "lamina.preset_apply"] in r["browser_panel"]
    assert r["unknown_icons"] == []


def test_user_presets_live_in_the_extension_user_directory(results):
    r = result_of(results, "user_folder")
    assert r["status"] == [["FINISHED"], ["FINISHED"]]
    folder = Path(r["folder"])
    assert r["folder"] == r["expected"]                                  # extension_path_user(..., "presets")
    assert folder.resolve().is_relative_to(Path(r["user_resources"]))
    assert not folder.resolve().is_relative_to(Path(r["extension_root"]))   # never inside the extension
    assert [p for p in r["saved"] if "folder-test" in p] == ["folder-test.json", "textures/folder-test/folder-tint.png"]
    assert not [p for p in r["saved"] if ".old" in p or ".new" in p]        # no staging leftovers
    assert "exists" in r["errors"][0] and "shipped preset" in r["errors"][1]
    # The render engine hands the folder to the backend, which then renders a scene naming it.
    assert r["env"] == {"LAMINA_PRESET_PATH": r["folder"]}
    assert r["with_env"]["code"] == 0, r["with_env"]["stderr"]
    assert r["without_env"]["code"] != 0 and "unknown material preset 'folder-test'" in r["without_env"]["stderr"]
    assert "folder-test" in r["listed_before"]
    assert r["deleted"] == ["FINISHED"]
    assert not [p for p in r["remaining"] if "folder-test" in p] and "folder-test" not in r["listed_after"]


def test_saved_preset_gets_a_thumbnail_in_the_background(results):
    r = result_of(results, "user_thumbnail")
    assert r["status"] == [["FINISHED"], ["FINISHED"]]
    # Saving does not wait for the render: it is still running when the operator returns
    # (checked by the job's state, not by a clock a loaded machine would fail).
    assert r["busy_after_save"], r["returned_after"]
    assert r["idle"]
    ended = [f for f in r["finished"] if f["path"].endswith("thumb-test.json")]
    # The second save replaced the first render: at most one was stopped, exactly one completed.
    completed = [f for f in ended if not f["cancelled"]]
    assert len(completed) == 1 and completed[0]["code"] == 0, ended
    assert r["thumbnail"] == str(Path(r["user_dir"]) / "thumbnails" / "thumb-test.png")
    assert r["size"] == [128, 128, 3]                 # the shipped thumbnails' stage and size
    assert r["deleted"] == ["FINISHED"] and not r["thumbnail_after_delete"]


def test_saving_repeatedly_while_thumbnails_render_does_not_crash(results):
    r = result_of(results, "repeated_saves")            # a crash would have failed the fixture
    assert r["status"] == ["FINISHED"] and r["idle"]
    completed = [f for f in r["ended"] if not f["cancelled"]]
    assert len(completed) == 1 and completed[0]["code"] == 0, r["ended"]
    assert len(r["ended"]) <= 40                       # every save that started a render was stopped
    assert r["deleted"] == ["FINISHED"]

def test_unrepresentable_fields_are_reported_and_rendered_until_edited(results):
    from cases.preset_cases import PARTIAL
    r = result_of(results, "dropped_fields")
    parse(PARTIAL, "partial", ROOT)                    # a valid material, so the check means something
    exact = r["exact"]
    assert exact["state"] == "EXACT"
    fields = sorted(d.split(":")[0] for d in exact["dropped"])
    assert fields == ["estimator", "interfaces[0].normal", "interfaces[0].transmission_color",
                      "interfaces[1].tint", "media[0].phase"]
    assert exact["linked"] == PARTIAL and r["exported_exact"]["Partial"] == PARTIAL
    assert r["exact_notes"] == []
    edited = r["edited"]
    assert edited["state"] == "EDITED" and r["exported_edited"]["Partial"] == edited["stack"]
    assert edited["stack"]["interfaces"][0]["roughness"] == 0.25 and "normal" not in json.dumps(edited["stack"])
    assert any("edited after applying preset 'partial'" in n and "interfaces[0].normal" in n for n in r["edited_notes"])
    assert r["reapplied"] == "EXACT"
