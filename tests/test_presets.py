"""Material preset library: validity, loading by name, rendering, energy, thumbnails, user presets.

Independent references used here: the issue's reference stack and the Guo et al. 2018 tables
(Guo et al. 2018, Fig. 2 and Fig. 8; benchmarks/scenes.py validation_stack) typed in below; energy conservation (R + T ≤ 1) from the sample weights of
each BSDF, whose mean is the directional albedo (standard error estimated from the same samples);
the committed thumbnails for the thumbnail layout (block means compared within Monte Carlo error).
"""
from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from backend import presets as P
from backend import preset_thumbnails as T
from backend.cli import main as cli_main
from backend.errors import LaminaError, SceneError
from backend.materials.base import ShadingContext
from backend.scene.loader import load_scene, load_scene_data

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = sorted(p.stem for p in P._preset_files(P.SHIPPED))


@pytest.fixture(autouse=True)
def _no_user_presets(monkeypatch):
    monkeypatch.delenv("LAMINA_PRESET_PATH", raising=False)


# --------------------------------------------------------------------------- the library

def test_library_size_and_coverage():
    assert len(SHIPPED) >= 20
    # The issue's list: reference stack, Guo validation stacks, and the named kinds of material.
    required = ["reference-microflake-3layer", "guo-coated-copper", "guo-microflake-stack",
                "guo-veach-gold-1", "guo-veach-gold-2", "guo-veach-gold-3", "guo-veach-gold-4",
                "jade-sheet", "magnifier-coat", "gabardine", "car-paint-red", "lacquered-wood",
                "brushed-aluminium-clearcoat", "ceramic-glaze-white", "pearlescent", "frosted-glass",
                "satin", "velvet", "coated-iron-rust"]
    assert not [n for n in required if n not in SHIPPED]


def test_every_preset_validates():
    from backend.cli.presets import validate_all
    records = validate_all([])
    assert {r["name"] for r in records} == set(SHIPPED)
    bad = [(r["name"], r["error"]) for r in records if not r["ok"]]
    assert not bad
    assert not [(r["name"], r["warnings"]) for r in records if r["warnings"]]


def test_the_preset_check_needs_no_compiled_code():
    """The add-on runs ``presets validate`` on every Save Preset while Blender waits: checking
    every shipped preset (layered stacks with microflake, SGGX, HG media; conductors,
    dielectrics, textures) must not import Numba or a compiled module (≈ 0.4 s of the check's
    ≈ 0.8 s; kernels/lazy.py). A bad preset is still refused with its field named."""
    import subprocess
    import sys
    code = ("import json, sys\n"
            "from backend.presets import all_presets, check_preset\n"
            "from backend.errors import LaminaError\n"
            "n = 0\n"
            "for info in all_presets():\n"
            "    check_preset(info.path); n += 1\n"
            "bad = json.loads(open(sys.argv[1]).read())\n"
            "try:\n"
            "    check_preset(sys.argv[1]); refused = ''\n"
            "except LaminaError as exc:\n"
            "    refused = str(exc)\n"
            "compiled = sorted(m for m in sys.modules if m == 'numba' or m.startswith('numba.')\n"
            "                  or (m.startswith('backend.kernels.') and m.split('.')[2] not in\n"
            "                      ('lazy', 'microfacet_codes', 'layered')))\n"
            "print(json.dumps({'checked': n, 'refused': refused, 'compiled': compiled}))\n")
    import tempfile
    with tempfile.TemporaryDirectory(prefix="pytest-preset-") as folder:
        good = json.loads(P.find_preset("car-paint-red").read_text())
        good["material"]["interfaces"][0]["roughness"] = -0.5
        bad = Path(folder) / "car-paint-red.json"
        bad.write_text(json.dumps(good))
        out = subprocess.run([sys.executable, "-c", code, str(bad)], capture_output=True, text=True,
                             cwd=Path(__file__).resolve().parent.parent)
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["checked"] >= 20
    assert "roughness" in r["refused"], r["refused"]
    assert r["compiled"] == [], r["compiled"][:10]


def test_reference_preset_is_the_issue_example_exactly():
    issue = {"type": "layered",
             "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.05, "distribution": "beckmann"},
                            {"type": "dielectric", "ior": 1.2, "roughness": 0.01},
                            {"type": "conductor", "metal": "Cu", "roughness": 0.05}],
             "media": [{"thickness": 1.0, "sigma_t": 0.5, "albedo": [0.5, 0.7, 0.95],
                        "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, 0.5, 0]}},
                       {"thickness": 1.0, "sigma_t": 0.5, "albedo": [0.5, 0.95, 0.5],
                        "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, -0.5, 0]}}]}
    assert P.load_user_preset("reference-microflake-3layer")["material"] == issue


def _stack(name):
    m = P.load_user_preset(name)["material"]
    return m["interfaces"], m["media"]


def test_guo_stacks_match_the_paper_tables():
    # Guo et al. 2018 (Fig. 2 top, Fig. 2 bottom, Fig. 8): Beckmann everywhere, unit thickness.
    ifs, med = _stack("guo-coated-copper")
    assert [i.get("roughness") for i in ifs] == [0.05, 0.05] and ifs[0]["ior"] == 1.5
    assert ifs[1]["metal"] == "Cu" and med[0]["sigma_t"] * med[0]["thickness"] == 1.0
    assert med[0]["albedo"] == [0.5, 0.7, 0.95] and med[0]["phase"] == {"type": "hg", "g": 0.5}
    assert all(i["distribution"] == "beckmann" for i in ifs)

    ifs, med = _stack("guo-microflake-stack")
    assert (ifs[0]["roughness"], ifs[0]["roughness_v"], ifs[0]["ior"]) == (0.05, 0.25, 1.5)
    assert (ifs[1]["ior"], ifs[1]["roughness"]) == (1.2, 0.01) and ifs[2]["metal"] == "Cu"
    assert [m["phase"]["orientation"] for m in med] == [[0.5, 0.5, 0], [0.5, -0.5, 0]]
    assert [m["albedo"] for m in med] == [[0.5, 0.7, 0.95], [0.5, 0.95, 0.5]]
    assert all(m["sigma_t"] == 0.5 and m["phase"]["stddev"] == 0.05 for m in med)

    for k, (top, bottom) in enumerate([(0.005, 0.005), (0.005, 0.1), (0.1, 0.005), (0.1, 0.1)], 1):
        ifs, med = _stack(f"guo-veach-gold-{k}")
        assert (ifs[0]["roughness"], ifs[1]["roughness"], ifs[1]["metal"]) == (top, bottom, "Au")
        assert med[0]["sigma_t"] == 1.0 and med[0]["albedo"] == [0.1, 0.5, 0.95]
        assert med[0]["phase"]["g"] == 0.0


def test_names_match_files_and_metadata_is_complete():
    for info in P.all_presets():
        doc = P.load_preset_document(info.path)
        assert doc["name"] == info.path.stem
        assert doc["description"].strip() and doc["tags"] and doc["category"]
        assert doc["units"], f"{info.name}: no units noted"
        # Every unit key names a field that the material uses.
        text = json.dumps(doc["material"])
        for key in doc["units"]:
            field = key.split(".")[-1]
            assert f'"{field}"' in text, (info.name, key)


# --------------------------------------------------------------------------- resolution

def _tiny_scene(material) -> dict:
    return {"format": "lamina-scene", "version": 1, "film": {"width": 4, "height": 4},
            "camera": {"type": "orthographic", "to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]],
                       "frame": [[1, 1, -1], [1, -1, -1], [-1, -1, -1], [-1, 1, -1]]},
            "materials": {"m": material}, "meshes": {"q": {"shape": "rectangle", "size": [2, 2]}},
            "objects": [{"name": "q", "mesh": "q", "materials": ["m"]}],
            "world": {"type": "constant", "color": [1, 1, 1]}}


def test_scene_material_by_preset_name():
    from backend.layered.material import LayeredMaterial
    sc = load_scene_data(_tiny_scene("guo-coated-copper"), "t.json")
    assert isinstance(sc.materials[0], LayeredMaterial)
    assert len(sc.materials[0].interfaces) == 2


def test_scene_unknown_preset_names_the_field():
    with pytest.raises(SceneError) as err:
        load_scene_data(_tiny_scene("car-paint"), "t.json")
    msg = str(err.value)
    assert msg.startswith("t.json: materials.m: unknown material preset 'car-paint'")
    assert "car-paint-red" in msg          # suggestion


def test_scene_preset_with_texture_resolves_relative_to_preset(tmp_path):
    # The scene lives elsewhere; the preset's texture path is relative to the preset file.
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(_tiny_scene("lacquered-wood")))
    sc = load_scene(path)
    assert sc.materials[0].uses_textures


def test_resolve_material_by_name_preset_file_and_material_file(tmp_path):
    from backend.layered.material import LayeredMaterial
    by_name = P.resolve_material("satin")
    by_file = P.resolve_material(str(P.find_preset("satin")))
    mfile = tmp_path / "m.json"
    mfile.write_text(json.dumps(P.load_user_preset("satin")["material"]))
    by_material = P.resolve_material(str(mfile))
    assert all(isinstance(m, LayeredMaterial) for m in (by_name, by_file, by_material))
    with pytest.raises(LaminaError, match="unknown material preset 'no-such'"):
        P.resolve_material("no-such")
    with pytest.raises(LaminaError, match="material file not found"):
        P.resolve_material(str(tmp_path / "missing.json"))
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"type": "layered", "interfaces": [{"type": "dielectric", "ior": -1}]}))
    with pytest.raises(SceneError) as err:
        P.resolve_material(str(bad))
    assert str(err.value).startswith(f"{bad}: interfaces[0].ior")


# --------------------------------------------------------------------------- user presets (add-on API)

def test_user_preset_round_trip_and_search_path(tmp_path, monkeypatch):
    material = copy.deepcopy(P.load_user_preset("car-paint-red")["material"])
    material["media"][0]["albedo"] = [0.1, 0.6, 0.2]
    path = P.save_user_preset(material, "My Green Paint", tmp_path, description="green", tags=["mine"])
    assert path == tmp_path / "my-green-paint.json"
    doc = P.load_user_preset("my-green-paint", tmp_path)
    assert doc["material"] == material and doc["label"] == "My Green Paint" and doc["tags"] == ["mine"]
    P.check_preset(path)                                  # a saved preset is a valid preset
    # Found by name once its folder is on LAMINA_PRESET_PATH (how the add-on passes it on).
    monkeypatch.setenv("LAMINA_PRESET_PATH", str(tmp_path))
    assert P.find_preset("my-green-paint") == path
    sc = load_scene_data(_tiny_scene("my-green-paint"), "t.json")
    assert sc.materials[0].media[0].albedo.bind(None).ravel().tolist() == [0.1, 0.6, 0.2]
    assert [p.name for p in P.list_user_presets(tmp_path)] == ["my-green-paint"]
    with pytest.raises(LaminaError, match="exists"):
        P.save_user_preset(material, "my-green-paint", tmp_path)
    P.save_user_preset(material, "my-green-paint", tmp_path, overwrite=True)
    P.delete_user_preset("my-green-paint", tmp_path)
    assert not path.exists()


def test_user_preset_refuses_shipped_names_and_invalid_materials(tmp_path):
    with pytest.raises(LaminaError, match="shipped preset"):
        P.save_user_preset({"type": "diffuse"}, "Satin", tmp_path)
    with pytest.raises(SceneError, match="roughness"):
        P.save_user_preset({"type": "conductor", "roughness": 3}, "bad", tmp_path)
    assert not list(tmp_path.iterdir())


# --------------------------------------------------------------------------- CLI

def test_cli_list_show_validate(capsys):
    assert cli_main(["presets", "list", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert sorted(p["name"] for p in listed) == SHIPPED
    assert cli_main(["presets", "show", "velvet", "--material"]) == 0
    assert json.loads(capsys.readouterr().out) == P.load_user_preset("velvet")["material"]
    assert cli_main(["presets", "validate", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["failed"] == 0
    assert cli_main(["presets", "show", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: unknown material preset 'nope'")
    # an empty listing names the categories (or tags) that exist
    categories = sorted({p["category"] for p in listed})
    assert cli_main(["presets", "list", "--category", "nope"]) == 0
    assert capsys.readouterr().out.strip() == f"no presets found (categories: {', '.join(categories)})"
    assert cli_main(["presets", "list", "--category", "metal", "--tag", "glass"]) == 0
    assert capsys.readouterr().out.strip() == "no presets found"     # both exist, just not together


# --------------------------------------------------------------------------- energy

def directional_albedo(material, theta_deg: float, n: int, seed: int):
    """R + T (all RGB channels) at incidence θ with its standard error.

    Uses the BSDF inspector's estimator (``bsdf albedo``, backend/cli/bsdf.py) when present;
    otherwise the same estimate here: the mean sample weight in importance mode is the fraction
    of incident flux leaving (delta lobes included); its standard error comes from the same
    samples. Textured materials are taken at UV (0.5, 0.5) as the inspector does.
    """
    try:
        from backend.cli.bsdf import albedo as inspector_albedo
    except ImportError:
        inspector_albedo = None
    if inspector_albedo is not None:
        out = inspector_albedo(material, theta_deg, 0.0, n, seed)
        return 1.0 - np.asarray(out["loss"]), np.asarray(out["loss_se"])
    from backend.materials.base import IMPORTANCE
    rng = np.random.default_rng(seed)
    t = np.radians(theta_deg)
    wi = np.tile([np.sin(t), 0.0, np.cos(t)], (n, 1))
    bsdf = material.bind(ShadingContext(np.full((n, 2), 0.5)))
    s = bsdf.sample(wi, rng, IMPORTANCE)
    w = np.asarray(s.weight, dtype=np.float64)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    return w.mean(axis=0), w.std(axis=0, ddof=1) / np.sqrt(n)


def test_energy_check_detects_a_gain():
    # A diffuse colour above 1 (accepted, as in Blender) must fail the bound used below.
    from backend.scene.reader import LoadContext, Node, dispatch
    from backend.materials import load_all
    m = dispatch(Node({"type": "diffuse", "color": [1.2, 1.2, 1.2]}, "", LoadContext("t")), load_all())
    total, se = directional_albedo(m, 45.0, 4000, 0)
    assert np.all(total > 1 + 3 * se)


@pytest.mark.parametrize("name", SHIPPED)
def test_energy_conservation(name):
    material = P.resolve_material(name)
    for k, theta in enumerate((0.0, 45.0, 80.0)):
        total, se = directional_albedo(material, theta, 6000, 12345 + k)
        assert np.all(total <= 1 + 3 * se), f"{name} θ={theta}: R+T = {total} ± {se}"
        assert np.all(total > 0), f"{name} θ={theta}: black"


# --------------------------------------------------------------------------- renders

@pytest.mark.parametrize("name", SHIPPED)
def test_preset_renders_without_nan(name):
    info = P.read_preset(P.find_preset(name))
    result = T.render_thumbnail(info, size=20, spp=2, workers=1)
    rgb = result.film.combined()
    assert rgb.shape == (20, 20, 3)
    assert np.all(np.isfinite(rgb)) and np.all(rgb >= 0)
    assert np.all(np.isfinite(result.film.variance_of_mean()))
    # The sphere (image centre) is not black.
    assert rgb[7:13, 7:13].mean() > 0


def test_committed_thumbnails_have_the_stage_layout():
    from backend.textures import read_image
    for name in SHIPPED:
        thumb = P.SHIPPED / "thumbnails" / f"{name}.png"
        assert thumb.is_file(), f"missing thumbnail for {name}: run `python -m backend presets thumbnails {name}`"
        pixels, _ = read_image(thumb)
        assert pixels.shape == (T.SIZE, T.SIZE, 3), name


def test_thumbnail_regenerates_with_the_committed_layout():
    """Re-render one preset at low spp; its block means agree with the committed thumbnail.

    The committed thumbnail is a T.SPP render passed through ``smooth_preview``. Per 16 × 16 px
    block the difference of means may come from Monte Carlo error (the film's variance of each
    pixel mean, pixels independent, plus the committed render's share), 8-bit quantisation (half
    a code value per pixel at most), and the smoothing, which moves a block's mean by at most
    what it moves the noisier low-spp image here (measured on it). Blocks with clipped pixels
    are skipped (the PNG stores min(1, value)).
    """
    from backend.textures import read_image, srgb_to_linear
    name, spp = "plastic-red-glossy", 4
    info = P.read_preset(P.find_preset(name))
    result = T.render_thumbnail(info, spp=spp, workers=1)
    film = result.film
    new = film.combined().astype(np.float64)
    var = film.variance_of_mean().astype(np.float64)
    smoothed = T.smooth_preview(new, var, film.albedo_image(), film.normal_image())
    raw, _ = read_image(info.thumbnail)
    old = srgb_to_linear(raw).astype(np.float64)
    assert new.shape == old.shape == (T.SIZE, T.SIZE, 3)
    b = 16
    z_max, used = 0.0, 0
    for y in range(0, T.SIZE, b):
        for x in range(0, T.SIZE, b):
            blk = (slice(y, y + b), slice(x, x + b))
            if raw[blk].max() >= 254.5 / 255 or new[blk].max() >= 1.0:
                continue
            k = b * b
            se = np.sqrt(var[blk].sum(axis=(0, 1))) / k * np.sqrt(1 + spp / T.SPP)
            top = float(raw[blk].max())
            quant = float(srgb_to_linear(np.float32(min(top + 0.5 / 255, 1.0))) - srgb_to_linear(np.float32(top)))
            shift = np.abs(smoothed[blk].mean(axis=(0, 1)) - new[blk].mean(axis=(0, 1)))
            d = np.abs(new[blk].mean(axis=(0, 1)) - old[blk].mean(axis=(0, 1)))
            z = np.maximum(d - shift - quant, 0.0) / np.maximum(se, 1e-9)
            z_max = max(z_max, float(z.max()))
            used += 1
    assert used >= 48
    assert z_max < 5.0, f"thumbnail differs from the committed one: max |z| = {z_max:.2f}"


def test_smooth_preview_keeps_edges_and_flattens_noise():
    # Independent check of the filter: a noisy two-tone image with an albedo edge.
    rng = np.random.default_rng(3)
    truth = np.zeros((32, 32, 3))
    truth[:, 16:] = 0.5
    truth[:, :16] = 0.1
    albedo = truth.copy()
    normal = np.zeros((32, 32, 3))
    normal[..., 2] = 1.0
    sigma = 0.05
    noisy = truth + rng.normal(0, sigma, truth.shape)
    out = T.smooth_preview(noisy, np.full(truth.shape, sigma ** 2), albedo, normal)
    assert np.abs(out - truth)[:, 4:12].std() < 0.5 * sigma      # noise reduced inside regions
    # A blur across the edge would be off by ≈ 0.18 there (> 2σ); the albedo guide prevents it.
    assert np.abs(out[:, 15] - 0.1).max() < 2 * sigma and np.abs(out[:, 16] - 0.5).max() < 2 * sigma


def test_gallery_page_is_current():
    page = T.GALLERY
    assert page.is_file()
    presets = [p for p in P.all_presets() if p.shipped]
    assert page.read_text(encoding="utf-8") == T.gallery_markdown(presets, page), \
        "docs/presets.md is stale: run `python -m backend presets gallery`"
    text = page.read_text(encoding="utf-8")
    for name in SHIPPED:
        assert f"thumbnails/{name}.png" in text


# --------------------------------------------------------------------------- showcase

def test_showcase_scene_loads_and_renders():
    from backend.layered.material import LayeredMaterial
    from backend.render import Renderer, RenderOptions
    path = ROOT / "showcase" / "showcase.json"
    sc = load_scene(path)
    assert not sc.warnings
    mats = dict(zip(sc.material_names, sc.materials))
    for slot in ("microflake", "amber", "enamel", "gold"):
        assert isinstance(mats[slot], LayeredMaterial)
    assert mats["enamel"].uses_textures                     # textured absorption over a conductor
    data = json.loads(path.read_text())
    kinds = [(l["type"], "ies" in l, "cutoff_angle" in l) for l in data["lights"]]
    assert ("point", True, False) in kinds and ("area", False, True) in kinds
    opts = RenderOptions(workers=1, spp=1, resolution=(32, 18))
    opts.apply(sc)
    rgb = Renderer(sc, str(path), opts).run().film.combined()
    assert np.all(np.isfinite(rgb)) and rgb.mean() > 0
