"""Scene export (Blender → scene description): structure, values, meshes, materials, speed."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bpy_harness import backend_renders, requires_bpy, result_of, run_cases

pytestmark = [pytest.mark.blender, requires_bpy]

CASES = ["reference_stack", "every_phase_kind", "full_scene", "mesh_arrays", "node_materials", "million_triangles"]

TOP_LEVEL = {"format", "version", "film", "camera", "render", "materials", "meshes", "objects", "lights", "world"}
LIGHT_FIELDS = {
    "point": {"power", "radius"}, "spot": {"power", "radius", "spot_size", "spot_blend"},
    "sun": {"strength", "angle"}, "area": {"shape", "size", "size_y", "power", "normalize"},
}


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    return run_cases("export_cases", CASES, tmp=tmp_path_factory.mktemp("export"))


def check_document(doc: dict, folder: Path) -> None:
    """Structure per docs/scene-format.md, checked independently of the backend's loader."""
    assert doc["format"] == "lamina-scene" and doc["version"] == 1
    assert {k for k in doc if not k.startswith("_")} <= TOP_LEVEL
    film = doc["film"]
    assert film["width"] >= 1 and film["height"] >= 1
    cam = doc["camera"]
    assert cam["type"] in ("perspective", "orthographic")
    assert np.array(cam["to_world"]).shape == (4, 4) and np.array(cam["frame"]).shape == (4, 3)
    for name, mesh in doc["meshes"].items():
        arrays = np.load(folder / mesh["file"], allow_pickle=False)
        p, t = arrays["positions"], arrays["indices"]
        assert p.dtype == np.float32 and p.ndim == 2 and p.shape[1] == 3, name
        assert t.dtype == np.int32 and t.shape[1] == 3 and t.min() >= 0 and t.max() < len(p), name
        if "normals" in arrays:
            assert arrays["normals"].shape in ((len(p), 3), (len(t), 3, 3)), name
        if "uvs" in arrays:
            assert arrays["uvs"].shape in ((len(p), 2), (len(t), 3, 2)), name
        if "material_indices" in arrays:
            assert arrays["material_indices"].shape == (len(t),), name
        for key in arrays:
            assert np.isfinite(arrays[key]).all(), (name, key)
    for obj in doc["objects"]:
        assert obj["mesh"] in doc["meshes"]
        assert np.array(obj["to_world"]).shape == (4, 4)
        assert all(m in doc["materials"] for m in obj["materials"])
    for light in doc["lights"]:
        kind = light["type"]
        assert LIGHT_FIELDS[kind] <= set(light), light
        assert len(light["color"]) == 3 and np.array(light["to_world"]).shape == (4, 4)
    assert doc["world"]["type"] in ("none", "constant", "environment")


def test_every_phase_kind_exports_what_the_loader_reads(results):
    """Every phase function of the schema (backend/layered/phase_schema.py) is in the panel's
    enum, and its default export loads as that kind."""
    from backend.layered.phase import parse_phase
    from backend.layered.phase_schema import PHASES
    from backend.scene.reader import LoadContext, Node
    got = result_of(results, "every_phase_kind")
    assert sorted(got) == sorted(k.enum for k in PHASES)
    for kind in PHASES:
        doc = got[kind.enum]
        assert doc["type"] == kind.name and set(doc) == {"type", *(p.key for p in kind.params)}
        spec = parse_phase(Node(doc, "media[0].phase", LoadContext("scene.json")))
        assert spec.type_name == kind.name and spec.directional == kind.directional


def test_reference_stack_is_exported_as_written(results):
    """The project's reference 3-layer stack (issue 3), built in the editor, exports to that JSON."""
    got = result_of(results, "reference_stack")["material"]
    expected = {"type": "layered",
                "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.05, "distribution": "beckmann"},
                               {"type": "dielectric", "ior": 1.2, "roughness": 0.01, "distribution": "ggx"},
                               {"type": "conductor", "metal": "Cu", "roughness": 0.05, "distribution": "ggx"}],
                "media": [{"thickness": 1.0, "sigma_t": 0.5, "albedo": [0.5, 0.7, 0.95],
                           "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, 0.5, 0.0]}},
                          {"thickness": 1.0, "sigma_t": 0.5, "albedo": [0.5, 0.95, 0.5],
                           "phase": {"type": "microflake", "stddev": 0.05, "orientation": [0.5, -0.5, 0.0]}}]}
    assert got == expected


def test_layered_pdf_choice_is_exported_as_the_backend_reads_it(results):
    """The panel's default is the backend's default (nothing written); the others are named as the
    scene format names them, and the backend accepts them."""
    from backend.layered.bsdf import Options
    from backend.layered.material import parse_options
    from backend.scene.reader import LoadContext, Node
    info = result_of(results, "reference_stack")
    assert info["default_pdf_mode"] == "LOBES" and Options().pdf == "lobes"
    assert info["layered_pdf"] == {"LOBES": None, "APPROXIMATE": "approx", "STOCHASTIC": "stochastic"}
    for name in ("approx", "stochastic"):
        assert parse_options(Node({"pdf": name}, "<test>", LoadContext("<test>")), None).pdf == name


def test_full_scene_structure_and_values(results):
    info = result_of(results, "full_scene")
    path = Path(info["path"])
    doc = json.loads(path.read_text())
    check_document(doc, path.parent)
    print(f"\nfull scene export: {info['seconds'] * 1e3:.1f} ms, {info['stats']}")

    objects = {o["_name"]: o for o in doc["objects"]}
    assert "HiddenPlane" not in objects
    assert objects["HoldoutPlane"]["holdout"] is True          # a transparent hole, still casts shadows
    assert "holdout" not in objects["Plane"]
    np.testing.assert_allclose(objects["Plane"]["to_world"], info["matrices"]["Plane"], atol=1e-6)
    np.testing.assert_allclose(objects["Sphere"]["to_world"], info["matrices"]["Sphere"], atol=1e-6)
    assert doc["materials"][objects["Sphere"]["materials"][0]]["type"] == "layered"
    cubes = [o for o in doc["objects"] if o["_name"] == "Cube"]
    assert len(cubes) == 3 and len({o["mesh"] for o in cubes}) == 1            # one mesh, 3 instances
    got = sorted(tuple(np.round(np.array(o["to_world"])[:3, 3], 6)) for o in cubes)
    want = sorted(tuple(np.round(np.array(m)[:3, 3], 6)) for m in info["instance_matrices"])
    assert got == want
    sub = np.load(path.parent / doc["meshes"][objects["SubCube"]["mesh"]]["file"])
    assert len(sub["indices"]) == info["subdivided_triangles"] == 48           # modifier applied

    lights = {l["_name"]: l for l in doc["lights"]}
    assert set(lights) == {"Point", "Spot", "Sun", "Area", "AreaSpread"}
    p = lights["Point"]
    assert p["type"] == "point" and p["power"] == 100.0 and p["radius"] == pytest.approx(0.25)
    assert Path(p["ies"]["file"]).name == "erco_narrow10_lm95.ies"
    s = lights["Spot"]
    assert s["spot_size"] == pytest.approx(40.0, abs=1e-4) and s["spot_blend"] == pytest.approx(0.2)
    assert s["color"] == pytest.approx([2.0, 1.0, 0.5])                       # colour × 2^exposure
    sun = lights["Sun"]
    assert sun["strength"] == 3.0 and sun["angle"] == pytest.approx(2.0, abs=1e-4)
    a = lights["Area"]
    assert (a["shape"], a["size"], a["size_y"], a["power"]) == ("rectangle", 0.5, 0.25, 50.0)
    assert a["cutoff_angle"] == pytest.approx(40.0, abs=1e-4) and a["beam_width"] == pytest.approx(20.0, abs=1e-4)
    # The world-space area the backend derives (local size × transform scale) is Blender's own.
    m = np.array(a["to_world"])[:3, :3]
    world_area = a["size"] * np.linalg.norm(m[:, 0]) * a["size_y"] * np.linalg.norm(m[:, 1])
    if info["area_world_area"] is not None:
        assert world_area == pytest.approx(info["area_world_area"], rel=1e-5)
    assert lights["AreaSpread"]["spread"] == pytest.approx(30.0, abs=1e-4)
    for name in ("Point", "Spot", "Sun", "Area"):
        np.testing.assert_allclose(lights[name]["to_world"], info["matrices"][name], atol=1e-6)
    assert doc["world"] == {"type": "constant", "color": [0.1, 0.2, 0.3], "strength": 0.5}
    np.testing.assert_allclose(doc["camera"]["frame"], info["camera_frame"], atol=1e-6)
    dof = doc["camera"]["dof"]
    assert dof["focus_distance"] == pytest.approx(info["focus_distance"], rel=1e-5)
    assert dof["aperture_radius"] == pytest.approx(0.035 / (2 * 2.8), rel=1e-6)   # f / (2 N), metres
    assert dof["blades"] == 6


@pytest.mark.skipif(not backend_renders(("diffuse", "layered"), ("point", "spot", "sun", "area"), ("constant",)),
                    reason="the backend cannot load every material/light type of this scene yet")
def test_full_scene_loads_in_backend(results):
    from backend.scene.loader import load_scene
    info = result_of(results, "full_scene")
    path = Path(info["path"])
    doc = json.loads(path.read_text())
    scene = load_scene(path)
    expected = sum(len(np.load(path.parent / doc["meshes"][o["mesh"]]["file"])["indices"]) for o in doc["objects"])
    assert scene.soup.count == expected
    assert scene.width == doc["film"]["width"] and len(scene.lights) >= len(doc["lights"])


def test_mesh_arrays_match_blender(results):
    r = result_of(results, "mesh_arrays")
    arrays, ref = r["arrays"], r["ref"]
    assert ref["domain"] == "CORNER"                      # a sharp edge forces corner normals
    np.testing.assert_array_equal(arrays["indices"], ref["indices"])
    np.testing.assert_array_equal(arrays["material_indices"], ref["material_indices"])
    np.testing.assert_allclose(arrays["positions"], ref["positions"], atol=0)
    np.testing.assert_allclose(arrays["normals"], ref["normals"], atol=1e-6)
    np.testing.assert_allclose(arrays["uvs"], ref["uvs"], atol=1e-7)
    assert r["slots"] == ["A", "B"]


def principled():
    """addon/export/principled.py, loaded on its own (it needs neither bpy nor the package)."""
    import importlib.util
    path = Path(__file__).resolve().parents[2] / "addon" / "export" / "principled.py"
    spec = importlib.util.spec_from_file_location("lamina_principled", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_node_materials_translation(results):
    r = result_of(results, "node_materials")
    mats = r["materials"]
    plastic = mats["Plastic"]
    assert plastic["type"] == "layered" and [i["type"] for i in plastic["interfaces"]] == ["dielectric", "diffuse"]
    assert plastic["interfaces"][0]["ior"] == pytest.approx(1.45)
    assert plastic["interfaces"][0]["roughness"] == pytest.approx(0.3 ** 2)     # α = r²
    # The body's albedo is chosen so the stack's albedo equals Cycles' (addon/export/principled.py):
    # brighter than the base colour (the stack keeps less light than Cycles' albedo scaling).
    mapped, _ = principled().principled_material({"base_color": [0.2, 0.4, 0.6], "roughness": 0.3, "ior": 1.45})
    assert plastic["interfaces"][1]["color"] == pytest.approx(mapped["interfaces"][1]["color"])
    assert all(a > b for a, b in zip(plastic["interfaces"][1]["color"], [0.2, 0.4, 0.6]))
    assert plastic["media"] == [{"thickness": 1.0, "sigma_t": 0.0}]
    coated = mats["Coated"]
    assert [i["type"] for i in coated["interfaces"]] == ["dielectric", "dielectric", "diffuse"]
    assert coated["interfaces"][0]["ior"] == pytest.approx(1.6)
    assert coated["interfaces"][0]["roughness"] == pytest.approx(0.01)
    assert len(coated["media"]) == 2
    gold = mats["Gold"]
    assert gold["type"] == "conductor" and gold["eta"] == [1.0, 1.0, 1.0]
    # A conductor with η = 1 reflects F0 = k²/(4 + k²) at normal incidence; F0 is the one whose
    # albedo equals Cycles' F82 metal of this base colour (1.0 is out of reach: clamped to 0.999).
    k = np.array(gold["k"])
    f0 = k * k / (4 + k * k)
    mapped, _ = principled().principled_material({"base_color": [1.0, 0.766, 0.336], "metallic": 1.0,
                                                  "roughness": 0.2})
    km = np.array(mapped["k"])
    np.testing.assert_allclose(f0, km * km / (4 + km * km), rtol=1e-5)
    assert f0[0] == pytest.approx(0.999, rel=1e-4) and abs(f0[1] - 0.766) < 0.05 and abs(f0[2] - 0.336) < 0.05
    assert gold["roughness"] == pytest.approx(0.04)
    glassy = mats["Glassy"]
    assert glassy["type"] == "dielectric" and glassy["ior"] == pytest.approx(1.33)
    glow = mats["Glow"]
    assert glow["emission"] == pytest.approx([4.0, 2.0, 1.0])
    glass = mats["GlassNode"]
    assert glass["type"] == "dielectric" and glass["roughness"] == pytest.approx(0.04)
    assert glass["transmission_color"] == pytest.approx([0.9, 1.0, 0.9])
    tex = mats["Textured"]["interfaces"]
    assert tex[1]["color"]["texture"].endswith(".pfm") and tex[0]["roughness"]["texture"].endswith(".pfm")
    assert r["textures"]["color"]["exists"] and r["textures"]["color"]["header"] == "PF"
    # Unsupported things arrive in ONE warning that names them.
    warning = r["warning"]
    assert warning.startswith("Lamina ignored or approximated:") and "\n" not in warning
    for needle in ("Noise Texture", "Sheen"):
        assert needle in warning, needle
    # A Mix Shader is rendered (backend/materials/mix.py); its unconnected inputs add no light.
    black = {"type": "diffuse", "color": [0.0, 0.0, 0.0]}
    assert mats["Mixed"] == {"type": "mix", "factor": 0.5, "materials": [black, black]}
    assert "Mix Shader" not in warning
    # A Normal Map node (tangent space, image texture) becomes the material's normal map, on a
    # Principled stack and on a plain BSDF; the image is read as stored (Non-Color).
    mapped = mats["NormalMapped"]
    assert mapped["type"] == "layered" and mapped["normal_strength"] == pytest.approx(0.7)
    assert mapped["normal"]["texture"] and mapped["normal"]["colorspace"] != "sRGB"
    plain = mats["DiffuseNormalMapped"]
    assert plain["type"] == "diffuse" and "normal_strength" not in plain
    assert plain["normal"]["texture"] == mapped["normal"]["texture"]
    assert "Normal Map" not in warning and "normal/bump" not in warning
    # A Bump node (image height) over a Normal Map: both, with the Bump node's settings.
    bumped = mats["Bumped"]
    assert bumped["normal"]["texture"] == mapped["normal"]["texture"]
    bump = bumped["bump"]
    assert bump["distance"] == pytest.approx(0.02) and bump["strength"] == pytest.approx(0.8)
    assert bump["invert"] is True and bump["height"]["texture"] and "channel" not in bump["height"]
    assert "Bump" not in warning


def test_million_triangle_export_time(results):
    r = result_of(results, "million_triangles")
    best = min(r["seconds"])
    print(f"\n1M-triangle export: {r['triangles']} triangles in {best:.3f} s "
          f"(runs: {', '.join(f'{s:.3f}' for s in r['seconds'])}), {r['bytes'] / 1e6:.0f} MB written")
    assert r["triangles"] == 2 * 725 * 725
    assert best < 2.0


@pytest.fixture(scope="module")
def more(tmp_path_factory):
    return run_cases("export_cases", ["world_and_images", "export_operator"], tmp=tmp_path_factory.mktemp("more"))


def test_environment_and_images(more):
    r = result_of(more, "world_and_images")
    world = r["world"]
    assert world["type"] == "environment" and world["strength"] == 2.0 and r["world_file_exists"]
    assert world["colorspace"] == "sRGB"
    # A Mapping rotation R in front of the texture is to_world = Rᵀ (docs/scene-format.md).
    np.testing.assert_allclose(world["to_world"], np.array(r["rotation"]).T, atol=1e-6)
    tex = r["texture"]
    assert tex["scale"] == [0.5, 1.0, 1.0] and r["packed_bytes_equal"]
    assert not r["notes"]


def test_export_operator_single_frame_and_animation(more):
    r = result_of(more, "export_operator")
    assert r["status"] == ["FINISHED"] and r["status_anim"] == ["FINISHED"] and r["mesh_file_exists"]
    assert r["frames"] == ["shot_0001.json", "shot_0002.json", "shot_0003.json"]
    assert r["heights"][0] == pytest.approx(0.0) and r["heights"][2] == pytest.approx(2.0)
    assert 0.0 < r["heights"][1] < 2.0 and r["single_height"] == pytest.approx(r["heights"][1])
    assert r["frame_after"] == 2                        # the current frame is restored
    assert r["mesh_bytes_stable"]                       # no time stamp in the .npz


def test_render_properties_follow_the_settings_table_and_export_what_the_loader_reads(tmp_path):
    """Blender's Render Properties are made from backend/render_settings.py: the same ranges and
    descriptions; the export writes each under the scene file's name, and the loader reads back
    exactly what Blender held."""
    import copy
    from backend.render_settings import SETTINGS
    from backend.scene.loader import load_scene_data
    from test_scene_validation import BASE
    r = result_of(run_cases("export_cases", ["render_settings"], tmp=tmp_path), "render_settings")
    for st in SETTINGS:
        if st.property_name is None:
            continue
        prop = r["props"][st.name]
        assert prop["description"] == st.doc, st.name
        default = st.blender_default if st.blender_default is not None else st.default
        assert prop["default"] == default and r["defaults"][st.name] == default, st.name
        if st.kind is not str and st.lo is not None:
            assert prop["min"] == st.lo, st.name
    assert r["props"]["spp"]["max"] == SETTINGS[0].hi          # 2^24 fits Blender's int
    assert r["missing"] == "error"
    for values in (r["defaults"], r["edited"]):
        data = copy.deepcopy(BASE)
        data["render"] = dict(values, missing_textures="magenta")
        s = load_scene_data(data, "scene.json").settings
        for name, value in values.items():
            assert getattr(s, name) == value, name
