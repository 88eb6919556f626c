"""showcase/showcase.blend: small, renders through the LAMINA engine, and is the same scene as
showcase/showcase.json (objects, meshes, materials, lights, camera, world), as the backend reads
both: each part of the two scene files is parsed by the backend's own loaders and compared."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bpy_harness import ROOT, requires_bpy, result_of, run_cases
from test_blender_presets import SKIP_ATTRS, object_diff

pytestmark = [pytest.mark.blender, requires_bpy]

BLEND = ROOT / "showcase" / "showcase.blend"
SCENE = ROOT / "showcase" / "showcase.json"
SMALL = (48, 27, 2)            # width, height, spp of the test renders
MAX_BYTES = 2 * 1024 * 1024
# Blender keeps matrices and vertex data in float32: entries of order 1 come back within a few
# float32 ulps (2^-23 ≈ 1.2e-7 relative); 1e-6 allows for the products of a few such entries.
F32_TOL = 1e-6


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("showcase")
    w, h, spp = SMALL
    return run_cases("showcase_cases", ["showcase"], tmp=tmp, timeout=300,
                     args={"showcase": {"blend": str(BLEND), "width": w, "height": h, "spp": spp}})


def _ctx(where: Path):
    from backend.scene.reader import LoadContext
    return LoadContext(str(where), where.parent)


def parse_mesh_entry(entry: dict, scene_path: Path):
    from backend.geometry.mesh import parse_mesh
    from backend.scene.reader import Node
    return parse_mesh(Node(entry, "mesh", _ctx(scene_path)))


def parse_material_entry(value, scene_path: Path):
    from backend.scene.loader import parse_material
    from backend.scene.reader import Node
    return parse_material(Node(value, "material", _ctx(scene_path)))


def parse_light_entry(entry: dict, scene_path: Path, world: bool = False):
    from backend.lights import load_all
    from backend.scene.reader import Node, dispatch
    lights, worlds = load_all()
    return dispatch(Node(entry, "world" if world else "light", _ctx(scene_path)), worlds if world else lights)


def test_blend_is_small_and_self_contained(results):
    r = result_of(results, "showcase")
    assert BLEND.stat().st_size < MAX_BYTES
    assert r["engine"] == "LAMINA"
    for name, path, packed in r["images"]:           # textures referenced from presets/, not packed
        assert path.startswith("//") and not packed, (name, path)
        assert (BLEND.parent / path[2:]).resolve().is_file(), path
    assert r["texts"] == ["erco_defined_spot_lm95.ies"]     # the IES profile travels with the file
    presets = {"microflake", "amber", "enamel", "gold", "table"}
    assert {m: s for m, s in r["links"].items() if m in presets} == {m: "EXACT" for m in presets}
    assert r["notes"] == []


def test_other_engines_show_each_stacks_colour(results):
    """Switched to Cycles or EEVEE, the .blend is not grey: each stack material's active output is
    the add-on's Principled approximation (addon/ops/viewport_colour.py), whose Base Color is the
    stack's albedo. Checked against the backend's own albedo of the scene file's material
    (30° incidence, another seed): each channel within 0.03 of it (R, or R + T for a stack that
    lets most light through; 20 000 directions each: standard error ≤ 0.004)."""
    import importlib.util

    from backend.cli.bsdf import albedo
    from backend.presets import find_preset
    spec = importlib.util.spec_from_file_location("viewport_colour", ROOT / "addon" / "viewport_colour.py")
    approx = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(approx)
    r = result_of(results, "showcase")
    ours = json.loads(SCENE.read_text())
    assert set(ours["materials"]) <= set(r["viewport"])
    for key, value in ours["materials"].items():
        shown = r["viewport"][key]
        assert shown.get("output") == "Lamina Viewport Output" and shown.get("node") == "Lamina Viewport", (key, shown)
        if isinstance(value, str):
            value = json.loads(find_preset(value).read_text())["material"]
        material = parse_material_entry(approx.constant_doc(value), SCENE)   # textures: their constants
        measured = albedo(material, 30.0, 0.0, 20_000, seed=99)
        reflect, transmit = np.array(measured["R"]), np.array(measured["T"])
        expected = reflect + transmit if transmit.mean() > reflect.mean() else reflect
        assert np.allclose(shown["base_color"], np.clip(expected, 0, 1), atol=0.03), (key, shown, expected)
        assert np.allclose(shown["solid"], shown["base_color"], atol=1e-6)
        print(f"\n{key}: base colour {np.round(shown['base_color'], 3)}, metallic {shown['metallic']:.0f}, "
              f"roughness {shown['roughness']:.2f}, transmission {shown['transmission']:.2f}")


def test_exported_scene_matches_the_scene_file(results):
    r = result_of(results, "showcase")
    ours = json.loads(SCENE.read_text())
    path = Path(r["scene"])
    theirs = json.loads(path.read_text())
    assert (theirs["film"]["width"], theirs["film"]["height"]) == (ours["film"]["width"], ours["film"]["height"])
    for key in ("spp", "max_bounces", "seed"):
        assert theirs["render"][key] == ours["render"][key], key
    # Camera: same placement, same image-plane directions (Blender's frame lies at another depth).
    assert np.allclose(theirs["camera"]["to_world"], ours["camera"]["to_world"], atol=F32_TOL)
    f_ours, f_theirs = np.array(ours["camera"]["frame"]), np.array(theirs["camera"]["frame"])
    assert np.allclose(f_theirs / -f_theirs[:, 2:], f_ours / -f_ours[:, 2:], atol=F32_TOL)

    by_name = {o["_name"]: o for o in theirs["objects"]}
    assert sorted(by_name) == sorted(o["name"] for o in ours["objects"])
    for obj in ours["objects"]:
        other = by_name[obj["name"]]
        assert np.allclose(other["to_world"], obj.get("to_world", np.eye(4)), atol=F32_TOL), obj["name"]
        a = parse_mesh_entry(ours["meshes"][obj["mesh"]], SCENE)
        b = parse_mesh_entry(theirs["meshes"][other["mesh"]], path)
        assert np.array_equal(a.positions[a.indices], b.positions[b.indices]), obj["name"]
        assert np.allclose(a.uvs, b.uvs, atol=F32_TOL), obj["name"]
        assert np.allclose(a.normals, b.normals, atol=F32_TOL), obj["name"]     # free float normals
        assert len(other["materials"]) == len(obj["materials"])
        for mine, exported in zip(obj["materials"], other["materials"]):
            diff = object_diff(parse_material_entry(ours["materials"][mine], SCENE),
                               parse_material_entry(theirs["materials"][exported], path), 0.0)
            assert not diff, (obj["name"], diff[:3])

    assert [l["type"] for l in theirs["lights"]] == [l["type"] for l in ours["lights"]]
    for mine, exported in zip(ours["lights"], theirs["lights"]):
        # An IES profile's name is its source (a file here, the .blend's Text there): a label.
        diff = object_diff(parse_light_entry(mine, SCENE), parse_light_entry(exported, path), F32_TOL,
                           skip=SKIP_ATTRS | {"name"})
        assert not diff, (mine["type"], diff[:3])
    assert "ies" in theirs["lights"][0] and theirs["lights"][1]["cutoff_angle"] == pytest.approx(40.0)
    diff = object_diff(parse_light_entry(ours["world"], SCENE, world=True),
                       parse_light_entry(theirs["world"], path, world=True), F32_TOL)
    assert not diff, diff[:3]


def read_exr(path: Path) -> np.ndarray:
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(str(path))
    assert not buf.has_error, buf.geterror()
    spec = buf.spec()
    names = list(spec.channelnames)
    pixels = buf.get_pixels(oiio.FLOAT).reshape(spec.height, spec.width, spec.nchannels)
    rgb = [names.index(c) for c in ("R", "G", "B")] if "R" in names else \
        [i for i, n in enumerate(names) if n.endswith((".R", ".G", ".B")) and "Combined" in n][:3]
    return pixels[..., rgb].astype(np.float64)


def test_blend_renders_like_the_scene_file(results, tmp_path):
    """F12 of the .blend (LAMINA, headless) gives the image the CLI gives for showcase.json.

    Both are 2-spp estimates of the same per-pixel expectations, made independent by a different
    seed for the CLI (with the same seed they agree to float rounding: the sample streams match).
    The per-pixel differences d are independent across pixels with mean zero, so the mean
    difference over N pixels has standard error sqrt(mean(d²) / N) (estimated here, per
    channel); it must lie within 4 of them."""
    r = result_of(results, "showcase")
    blend = read_exr(Path(r["render"]))
    w, h, spp = SMALL
    out = tmp_path / "cli.exr"
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(SCENE), "-o", str(out),
                           "--resolution", f"{w}x{h}", "--spp", str(spp), "--workers", "1", "--seed", "7"],
                          capture_output=True, text=True, cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 0, proc.stderr
    cli = read_exr(out)
    assert blend.shape == cli.shape == (h, w, 3)
    assert np.isfinite(blend).all() and (blend >= 0).all()
    assert (blend.sum(axis=2) > 0).mean() > 0.9           # lit nearly everywhere (table, wall, floor)
    d = (blend - cli).reshape(-1, 3)
    se = np.sqrt((d * d).mean(axis=0) / d.shape[0])
    assert np.all(np.abs(d.mean(axis=0)) <= 4 * se), (d.mean(axis=0), se)
    # ... and not trivially zero: the blend's mean lies 4 of *its own* standard errors above 0.
    # Both renders have the same per-pixel variance, so that standard error is se/√2 (se is the
    # difference's); at 2 spp a single firefly can make se/√2 a large part of the mean.
    se_one = se / np.sqrt(2.0)
    assert np.all(blend.reshape(-1, 3).mean(axis=0) > 4 * se_one), (blend.reshape(-1, 3).mean(axis=0), se_one)
