"""Issue 18: no traceback, hang or silently wrong image on any input; a lost worker loses nothing.

Each family of the issue has a test here: the input, the one-line error (naming file and field)
or warning it gets, and — where rendering goes on — that the image is finite. The seeded fuzz
test is tests/test_fuzz.py; the worker-kill experiment with random moments is
benchmarks/worker_kill.py.
"""
import copy
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from backend import cli, limits
from backend.errors import SceneError
from backend.imageio import read_exr
from backend.scene.loader import load_scene, load_scene_data
from conftest import DATA, ROOT
from render_util import front_perspective, scene

BASE = {
    "format": "lamina-scene", "version": 1,
    "film": {"width": 16, "height": 12},
    "camera": {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0, -1, -5], [0, 1, 0, 0], [0, 0, 0, 1]],
               "frame": [[0.36, 0.27, -1], [0.36, -0.27, -1], [-0.36, -0.27, -1], [-0.36, 0.27, -1]]},
    "render": {"spp": 2},
    "materials": {"grey": {"type": "diffuse", "color": 0.5}},
    "meshes": {"tri": {"positions": [[-1, 0, -1], [1, 0, -1], [0, 0, 1]], "indices": [[0, 1, 2]]}},
    "objects": [{"mesh": "tri", "materials": ["grey"]}],
    "lights": [{"type": "point", "to_world": [[1, 0, 0, 0], [0, 1, 0, -3], [0, 0, 1, 1], [0, 0, 0, 1]],
                "power": 100}],
}
SUN = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]]


def edited(edit) -> dict:
    data = copy.deepcopy(BASE)
    edit(data)
    return data


def layered(depth: int) -> dict:
    """A layered stack with ``depth`` stacks nested inside it."""
    m = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5}, {"type": "diffuse"}],
         "media": [{"thickness": 0.1, "sigma_t": 1, "albedo": 0.5}]}
    for _ in range(depth):
        m = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5}, m],
             "media": [{"thickness": 0.1, "sigma_t": 1, "albedo": 0.5}]}
    return m


@pytest.fixture
def run(tmp_path, capsys):
    """Run the CLI in-process on a scene (dict or text); returns (code, stderr lines, EXR or None)."""
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}

    def go(data, *extra, command="render", name="scene.json"):
        path = tmp_path / name
        path.write_text(data if isinstance(data, str) else json.dumps(data))
        out = tmp_path / "out.exr"
        if out.exists():
            out.unlink()
        args = [command, str(path)] + (["-o", str(out), "--workers", "1", "--progress", "none"]
                                       if command == "render" else []) + list(extra)
        try:
            code = cli.main(args)
        except SystemExit as exc:
            code = exc.code
        err = capsys.readouterr().err
        assert "Traceback" not in err
        lines = [ln for ln in err.splitlines() if ln.strip()]
        image = read_exr(out)[0] if command == "render" and code == 0 else None
        return code, lines, image

    yield go
    for s, h in handlers.items():
        signal.signal(s, h)


def one_error(lines) -> str:
    errors = [ln for ln in lines if ln.startswith("error: ")]
    assert len(errors) == 1, lines
    return errors[0]


# --------------------------------------------------------------------------- tracebacks → errors

DEEP = "[" * 100_000 + "]" * 100_000


@pytest.mark.parametrize("text, expected", [
    ('{"format": "lamina-scene", "x": ' + DEEP + "}", "arrays/objects nested deeper than 64 levels (at line 1)"),
    (json.dumps(BASE).replace('"color": 0.5', '"color": ' + "[" * 2000 + "0.5" + "]" * 2000),
     "arrays/objects nested deeper than 64 levels"),
    (json.dumps(BASE).replace('"color": 0.5', '"color": ' + "[" * 70 + "0.5" + "]" * 70),
     "materials.grey.color[0][0][0][0][0]…: arrays/objects nested deeper than 64 levels"),
    (json.dumps(BASE).replace('"spp": 2', '"spp": ' + "9" * 5000),
     "render.spp: expected an integer in [1, 16777216], got an integer of 5000 digits"),
    (json.dumps(BASE).replace('"power": 100', '"power": ' + "9" * 400),
     "lights[0].power: expected a number >= 0, got an integer of 400 digits"),
    (json.dumps(BASE).replace("[[0, 1, 2]]", "[[0, 1, " + "1" + "0" * 30 + "]]"),
     "meshes.tri.indices: indices: an integer is out of range"),
])
def test_inputs_that_raised_give_one_line_naming_the_field(run, text, expected):
    for command in ("validate", "render"):
        code, lines, _ = run(text, command=command)
        assert code == 2 and expected in one_error(lines), (command, lines)


def wide_stack(dielectrics: int) -> dict:
    """``dielectrics`` rough dielectric interfaces over a diffuse base."""
    return {"type": "layered",
            "interfaces": [{"type": "dielectric", "ior": 1.5 if i % 2 == 0 else 1.3, "roughness": 0.1}
                           for i in range(dielectrics)] + [{"type": "diffuse"}],
            "media": [{"thickness": 0.1, "sigma_t": 1, "albedo": 0.5}] * dielectrics}


def test_layered_nesting_is_limited(tmp_path):
    """Nested stacks cost a factor of ~10 per level with the NumPy walks (60 levels never
    finished); 3 levels load, the 4th is refused naming the field, and so are 17 interfaces (the
    compiled stack table holds 16; issue 39: 17 to 64 passed the loader and raised a TypeError)."""
    load_scene_data(edited(lambda d: d["materials"].update(grey=layered(2))), "s.json")
    with pytest.raises(SceneError) as info:
        load_scene_data(edited(lambda d: d["materials"].update(grey=layered(3))), "s.json")
    assert str(info.value).startswith("s.json: materials.grey.interfaces[1].interfaces[1].interfaces[1]: "
                                      "layered materials nested 4 deep; at most 3")
    from backend.kernels.layered.table import MAX_INTERFACES
    assert limits.MAX_STACK_INTERFACES == MAX_INTERFACES       # the loader's limit is the kernels'
    wide = wide_stack(16)
    with pytest.raises(SceneError) as info:
        load_scene_data(edited(lambda d: d["materials"].update(grey=wide)), "s.json")
    assert "materials.grey.interfaces: 17 interfaces; at most 16" in str(info.value)
    # Nested stacks count with their own interfaces: 8 + 9 = 17 after flattening.
    nested = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5}] * 8 + [wide_stack(8)],
              "media": [{"thickness": 0.1}] * 8}
    with pytest.raises(SceneError) as info:
        load_scene_data(edited(lambda d: d["materials"].update(grey=nested)), "s.json")
    assert "materials.grey.interfaces: 17 interfaces (nested stacks included); at most 16" in str(info.value)
    deep = json.dumps(edited(lambda d: d["materials"].update(grey=layered(40))))
    (tmp_path / "deep.json").write_text(deep)
    with pytest.raises(SceneError) as info:
        load_scene(tmp_path / "deep.json")
    assert "nested deeper than 64 levels" in str(info.value)


def test_film_that_does_not_fit_in_memory_is_refused_before_allocating(run, monkeypatch):
    """65536² is inside the documented side limit but needs terabytes: validate and render
    both refuse it (with the memory it needs); --resolution is checked the same way."""
    big = edited(lambda d: d["film"].update(width=65536, height=65536))
    for command in ("validate", "render"):
        code, lines, _ = run(big, command=command)
        msg = one_error(lines)
        assert code == 2 and "film: a 65536 × 65536 film needs about" in msg and "available" in msg
    monkeypatch.setattr(limits, "available_memory", lambda: 64 << 20)     # a 64 MiB machine
    code, lines, _ = run(BASE, "--resolution", "4000x4000")
    assert code == 2 and "--resolution 4000x4000: a 4000 × 4000 film needs about 7.5 GiB" in one_error(lines)
    code, lines, image = run(BASE, "--resolution", "64x48")
    assert code == 0 and image.shape[:2] == (48, 64)


def test_unusable_file_paths_name_the_field(run, tmp_path, capsys):
    long_texture = edited(lambda d: d["materials"]["grey"].update(color={"texture": "a" * 100_000 + ".png"}))
    code, lines, _ = run(long_texture)
    msg = one_error(lines)
    assert code == 2 and "materials.grey.color.texture: file path too long (100004 characters, at most 4096)" in msg
    assert len(msg) < 400
    long_name = edited(lambda d: d["meshes"].update(tri={"file": "m" * 300 + ".npz"}))
    code, lines, _ = run(long_name)
    assert code == 2 and "meshes.tri.file: file path has a name longer than 255 bytes" in one_error(lines)
    nul = edited(lambda d: d["lights"][0].update(ies={"file": "lamp\x00.ies"}))
    code, lines, _ = run(nul)
    assert code == 2 and "lights[0].ies.file: a file path cannot contain a NUL character" in one_error(lines)
    code = cli.main(["validate", str(tmp_path / ("y" * 5000 + ".json"))])
    assert code == 2 and "file path too long (5" in capsys.readouterr().err


def test_damaged_mesh_files_are_refused(run, tmp_path):
    src = (ROOT / "showcase" / "meshes" / "cup.npz").read_bytes()
    cases = {
        "cut.npz": src[: len(src) // 2],
        "empty.npz": b"",
        "garbage.npz": b"PK\x03\x04" + bytes(200),
    }
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        code, lines, _ = run(edited(lambda d: d["meshes"].update(tri={"file": name})))
        msg = one_error(lines)
        assert code == 2 and f"meshes.tri.file: cannot read mesh file {tmp_path / name}" in msg, (name, msg)
    # a small archive that declares a huge array (a decompression bomb) is refused from its header
    import io, zipfile
    buf = io.BytesIO()
    header = np.lib.format.header_data_from_array_1_0(np.zeros((1, 3), np.float32))
    header["shape"] = (10 ** 11, 3)
    with zipfile.ZipFile(buf, "w") as zf:
        with zf.open("positions.npy", "w") as f:
            np.lib.format.write_array_header_1_0(f, header)
    (tmp_path / "bomb.npz").write_bytes(buf.getvalue())
    code, lines, _ = run(edited(lambda d: d["meshes"].update(tri={"file": "bomb.npz"})))
    assert code == 2 and "its arrays need 1117.6 GiB" in one_error(lines)
    # complex positions, string or boolean indices are not silently converted
    np.savez(tmp_path / "complex.npz", positions=np.array([[0, 0, 0], [1, 0, 0], [0, 1j, 1]]),
             indices=np.array([[0, 1, 2]]))
    code, lines, _ = run(edited(lambda d: d["meshes"].update(tri={"file": "complex.npz"})))
    assert code == 2 and "positions: expected real numbers of shape (V, 3), got (3, 3) complex128" in one_error(lines)
    for indices, what in (([["0", "1", "2"]], "got '0'"), ([[0, 1, True]], "got true"), ([[0, 1, 2.0]], "got 2.0")):
        code, lines, _ = run(edited(lambda d: d["meshes"]["tri"].update(indices=indices)))
        assert code == 2 and f"meshes.tri.indices: indices[0][" in one_error(lines) and what in one_error(lines)


def test_unknown_field_names_are_not_echoed_whole(run):
    code, lines, _ = run(edited(lambda d: d.update({"x" * 10_000_000: 1})))
    msg = one_error(lines)
    assert code == 2 and "… (10000000 characters): unknown field" in msg and len(msg) < 400
    code, lines, _ = run(edited(lambda d: d["objects"][0].update(materials=["m" * 100_000])))
    assert code == 2 and len(one_error(lines)) < 400 and "unknown material" in one_error(lines)


# --------------------------------------------------------------------------- hangs

def test_spp_on_the_command_line_has_the_scene_limit(run):
    code, lines, _ = run(BASE, "--spp", str(10 ** 15))
    assert code == 2 and "--spp: expected an integer in [1, 16777216]" in lines[-1]


# --------------------------------------------------------------------------- silently wrong

@pytest.mark.parametrize("edit, expected", [
    (lambda d: d["materials"]["grey"].update(color=1e308),
     "materials.grey.color[0]: expected a number in [0, 1e+30] (larger values overflow while rendering), got 1e+308"),
    (lambda d: d["materials"]["grey"].update(emission=[1e308, 0, 0]), "materials.grey.emission[0]: expected a number in [0, 1e+30]"),
    (lambda d: d["lights"][0].update(power=1e308), "lights[0].power: expected a number in [0, 1e+30]"),
    (lambda d: d["lights"][0].update(color=[1, 1e31, 1]), "lights[0].color[1]: expected a number in [0, 1e+30]"),
    (lambda d: d["camera"]["to_world"][0].__setitem__(0, 1e308),
     "camera.to_world[0][0]: expected a number in [-1e+12, 1e+12], got 1e+308"),
    (lambda d: d["objects"][0].update(to_world=[[1e11, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]) or
     d["meshes"]["tri"].update(positions=[[-100, 0, -1], [100, 0, -1], [0, 0, 1]]),
     "objects[0].to_world: mesh 'tri' placed by this matrix reaches the coordinate 1e+13"),
    (lambda d: d["camera"]["to_world"].__setitem__(3, [0, 0, 0.5, 1]),
     "camera.to_world[3]: expected [0, 0, 0, 1] (an affine transform, as Blender's matrix_world), got [0, 0, 0.5, 1]"),
    (lambda d: d["lights"][0].update(ies={"data": IES.replace(" 1 3 1 1 2", " 1e308 3 1 1 2")}),
     "lights[0].ies.data: line 3: expected the candela multiplier: a finite number of magnitude at most 1e+30, got '1e308'"),
    (lambda d: d["lights"][0].update(ies={"data": IES.replace("100 50 0", "1e308 50 0")}),
     "lights[0].ies.data: line 7: expected candela value 1 of 3"),
    (lambda d: d["lights"][0].update(ies={"data": IES.replace(" 1 3 1 1 2", " 1e20 3 1 1 2")}),
     "lights[0].ies.data: line 3: the candela multiplier (1e+20) × ballast factor (1) × ballast-lamp factor (1) × "
     "the largest candela value (100) = 1e+22 cd, above 1e+15 cd"),
    (lambda d: d["render"].update(layered={"estimatr": "uni"}),
     "render.layered.estimatr: unknown field (allowed: estimator, max_vertices, mis, pdf, pdf_constant)"),
])
def test_values_that_rendered_inf_or_empty_are_refused_with_the_range(edit, expected):
    with pytest.raises(SceneError) as info:
        load_scene_data(edited(edit), "s.json")
    assert str(info.value).startswith("s.json: " + expected), str(info.value)


IES = "IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 3 1 1 2 0 0 0\n1 1 100\n0 45 90\n0\n100 50 0\n"


def test_legal_but_overflowing_values_render_finite_with_a_warning(run):
    """Values inside the limits can still multiply past the float32 range of an EXR (here an
    emitter of 1e30 × 1e30 seen directly): every written value is finite, and a warning says
    how many were clamped."""
    data = edited(lambda d: d["materials"].update(grey={"type": "emission", "color": 1e30, "strength": 1e30}))
    data["film"] = {"width": 8, "height": 6}
    data["camera"]["frame"] = [[0.01, 0.01, -1], [0.01, -0.01, -1], [-0.01, -0.01, -1], [-0.01, 0.01, -1]]
    code, lines, image = run(data)
    assert code == 0 and np.all(np.isfinite(image))
    assert np.all(image[:, :, 0] == np.finfo(np.float32).max)          # the emitter fills the view
    (warning,) = [ln for ln in lines if "were not finite or beyond" in ln]
    assert warning.startswith("warning: ") and "clamped" in warning
    code, lines, image = run(edited(lambda d: d["lights"][0].update(power=1e9)), "--half")
    assert code == 0 and np.all(np.isfinite(image)) and image[:, :, :3].max() == 65504.0
    assert any("beyond ±65504 (half float" in ln for ln in lines)


def test_dark_lights_warn_by_name(run, tmp_path):
    zero_ies = IES.replace("100 50 0", "0 0 0")
    data = edited(lambda d: d["lights"].extend([
        {"type": "area", "_name": "Softbox", "to_world": SUN, "power": 10, "size": 0},
        {"type": "point", "_name": "Bulb", "to_world": SUN, "power": 50, "ies": {"data": zero_ies}},
        {"type": "sun", "to_world": SUN, "strength": 0},
        {"type": "spot", "to_world": SUN, "power": 10, "color": [0, 0, 0]}]))
    code, lines, image = run(data, command="validate")
    assert code == 0
    warnings = [ln for ln in lines if ln.startswith("warning: ")]
    assert warnings == [
        f"warning: {tmp_path / 'scene.json'}: lights[1]: light ('Softbox') emits nothing (size 0: zero area): it is dark",
        f"warning: {tmp_path / 'scene.json'}: lights[2]: light ('Bulb') emits nothing (its IES table is zero everywhere): it is dark",
        f"warning: {tmp_path / 'scene.json'}: lights[3]: light emits nothing (strength 0): it is dark",
        f"warning: {tmp_path / 'scene.json'}: lights[4]: light emits nothing (black colour): it is dark"]


def test_inputs_that_make_a_light_or_an_object_vanish_warn(run, tmp_path):
    """issue 39: an IES candela multiplier of 1e-320 (a denormal) rendered a dark light, and a
    dielectric of IOR 1e-300 made its object vanish, both without a word."""
    faint_ies = IES.replace("1 -1 1 3", "1 -1 1e-320 3")
    data = edited(lambda d: d["lights"].append(
        {"type": "point", "_name": "Bulb", "to_world": SUN, "power": 50, "ies": {"data": faint_ies}}))
    data["materials"]["grey"] = {"type": "dielectric", "ior": 1e-300}
    code, lines, image = run(data)
    assert code == 0 and np.all(np.isfinite(image))
    warnings = [ln for ln in lines if ln.startswith("warning: ")]
    where = tmp_path / "scene.json"
    assert any(w.startswith(f"warning: {where}: lights[1]: light ('Bulb') emits only ") and
               "practically dark" in w and "IES multiplier" in w for w in warnings), warnings
    assert f"warning: {where}: materials.grey.ior: index of refraction 1e-300 is far outside real materials'" \
        in "\n".join(warnings), warnings
    # Real indices, bubbles (0.75) and ordinary lights stay quiet.
    for ior in (0.75, 1.0, 1.33, 2.42, 4.0):
        quiet = edited(lambda d: d["materials"].update(grey={"type": "dielectric", "ior": ior}))
        code, lines, _ = run(quiet, command="validate")
        assert code == 0 and not [ln for ln in lines if ln.startswith("warning: ")], (ior, lines)


def test_a_scene_of_several_gib_is_announced_with_its_memory_and_load_time(run, monkeypatch, tmp_path):
    """issue 39: 10^6 lights (4.2 GiB, 84 s) and a small compressed mesh expanding to 10 M
    triangles (4.45 GiB) loaded without a word. The estimate comes from the counts (measured
    constants in backend/limits.py) and is printed before the loading, not after it."""
    message = limits.heavy_scene_message(0, 1_000_000)
    assert message.startswith("0 triangles (instances counted) and 1000000 lights: loading will take about 4.2 GiB")
    assert message.endswith("and about 90 s")
    assert "about 8.4 GiB" in limits.heavy_scene_message(10_000_000, 0)
    assert limits.heavy_scene_message(1_000_000, 1000) is None          # 0.85 GiB: no word
    # Through the CLI, with the threshold lowered so that a small scene crosses it: 400 lights
    # (one of them dark) and 1000 instances of the triangle.
    monkeypatch.setattr(limits, "HEAVY_SCENE_BYTES", 1 << 20)
    data = edited(lambda d: d["lights"].extend(
        [{"type": "point", "to_world": SUN, "power": 1}] * 398 + [{"type": "point", "to_world": SUN, "power": 0}]))
    data["objects"] = data["objects"] * 1000
    code, lines, image = run(data)
    assert code == 0 and np.all(np.isfinite(image))
    warnings = [ln for ln in lines if ln.startswith("warning: ")]
    assert re.fullmatch(re.escape(f"warning: {tmp_path / 'scene.json'}: 1000 triangles (instances counted) and "
                                  f"400 lights: loading will take about 3 MiB of memory (of ") + r"[0-9.]+ [GM]iB"
                        + re.escape(" available) and about 0 s"), warnings[0]), warnings
    assert any("lights[399]" in w and "emits nothing" in w for w in warnings[1:])   # after it: the load's own
    assert sum("instances counted" in w for w in warnings) == 1                      # said once


def test_accepted_and_ignored_inputs_now_warn_or_fail(run):
    code, lines, _ = run(edited(lambda d: d["camera"].update(
        dof={"focus_distance": 5, "aperture_radius": 0.1, "blades": 2})), command="validate")
    assert code == 0 and any("camera.dof.blades: 2 blade(s) make a round aperture" in ln for ln in lines)
    code, lines, _ = run(edited(lambda d: d["render"].update(layered={"estimator": "uni"})), command="validate")
    assert code == 0 and any("render.layered: no layered material with two or more interfaces" in ln for ln in lines)
    code, lines, _ = run(edited(lambda d: d["render"].update(layered={"estimator": "uni"}) or
                                d["materials"].update(grey=layered(0))), command="validate")
    assert code == 0 and not any("render.layered" in ln for ln in lines)


def test_a_sun_of_180_degrees_is_the_whole_sky_hemisphere():
    """Blender allows a sun angle of 180° (its maximum) and Cycles renders it: a hemisphere of
    radiance E/π around the sun direction. So a surface facing the sun gets E, one at right
    angles E/2 (∫ over the quarter sphere), as the formulas say — nothing is ignored."""
    from backend.lights.sun import SunLight
    from lights_util import K_SIGMA, nee_irradiance
    E = 2.0
    sun = SunLight(np.eye(4), E, np.ones(3), np.radians(180.0))
    rng = np.random.default_rng(5)
    for normal, expected in (([0, 0, 1], E), ([1, 0, 0], E / 2)):
        mean, se, _ = nee_irradiance(sun, [0, 0, 0], normal, 40000, rng)
        assert np.all(np.abs(mean - expected) <= K_SIGMA * se), (normal, mean, se)


def test_validate_and_render_accept_the_same_scenes(run):
    cases = [BASE, edited(lambda d: d["film"].update(width=65536, height=65536)),
             edited(lambda d: d["materials"].update(grey=layered(3))),
             edited(lambda d: d["lights"][0].update(power=1e31)),
             edited(lambda d: d["render"].update(layered={"mis": False})),
             edited(lambda d: d["camera"].update(dof={"focus_distance": 1, "aperture_radius": 1, "ratio": 1e4})),
             # issue 39: these two passed validate and raised at render (TypeError, NotImplementedError)
             edited(lambda d: d["materials"].update(grey=wide_stack(16))),
             edited(lambda d: d["materials"].update(grey={"type": "layered", "interfaces": [{"type": "null"}]}))]
    codes = []
    for data in cases:
        v, _, _ = run(data, command="validate")
        r, _, image = run(data)
        assert v == r, (v, r, data)
        assert image is None or np.all(np.isfinite(image))
        codes.append(v)
    assert codes.count(0) >= 1 and codes.count(2) >= 5, codes     # both outcomes are exercised
    # The widest stack the kernels hold renders.
    code, _, image = run(edited(lambda d: d["materials"].update(grey=wide_stack(15))))
    assert code == 0 and np.all(np.isfinite(image)) and image[..., :3].max() > 0


def test_a_stack_whose_only_interface_is_null_is_refused_naming_the_field(run):
    code, lines, _ = run(edited(lambda d: d["materials"].update(
        grey={"type": "layered", "interfaces": [{"type": "null"}]})), command="validate")
    assert code == 2 and len(lines) == 1
    assert "materials.grey.interfaces[0].type: a stack whose only interface is 'null' has no surface" in lines[0]
    # Two null interfaces bound a medium: a volume slab, which renders.
    slab = {"type": "layered", "interfaces": [{"type": "null"}, {"type": "null"}],
            "media": [{"thickness": 0.1, "sigma_t": 1, "albedo": 0.5}]}
    code, _, image = run(edited(lambda d: d["materials"].update(grey=slab)))
    assert code == 0 and np.all(np.isfinite(image))


def test_presets_that_refer_to_each_other_are_a_cycle_named_in_one_line(run, tmp_path, monkeypatch):
    """issue 39: user presets mixing each other (or themselves) raised RecursionError."""
    folder = tmp_path / "user-presets"
    folder.mkdir()

    def preset(name, material):
        (folder / f"{name}.json").write_text(json.dumps(
            {"format": "lamina-preset", "version": 1, "name": name, "material": material}))

    mix = lambda a, b: {"type": "mix", "factor": 0.5, "materials": [a, b]}
    preset("ring-a", mix({"type": "diffuse"}, "ring-b"))
    preset("ring-b", mix("ring-c", {"type": "diffuse"}))
    preset("ring-c", mix("ring-a", {"type": "diffuse"}))
    preset("self", mix("self", {"type": "diffuse"}))
    preset("fine", mix("ring-free", {"type": "diffuse", "color": 0.2}))
    preset("ring-free", {"type": "diffuse", "color": 0.7})
    monkeypatch.setenv("LAMINA_PRESET_PATH", str(folder))
    for name, cycle in (("ring-a", "ring-a → ring-b → ring-c → ring-a"), ("self", "self → self")):
        for command in ("validate", "render"):
            code, lines, _ = run(edited(lambda d: d["materials"].update(grey=name)), command=command)
            assert code == 2 and len(lines) == 1, lines
            assert f"presets refer to each other in a cycle: {cycle}" in lines[0], lines
    # A preset used twice, without a cycle, still loads.
    code, _, image = run(edited(lambda d: d["materials"].update(
        grey=mix("fine", "ring-free"))))
    assert code == 0 and np.all(np.isfinite(image))


# --------------------------------------------------------------------------- temporary files

def test_temp_file_of_a_write_killed_by_sigkill_is_removed_by_the_next_render(tmp_path):
    """A process killed (SIGKILL) while writing leaves its hidden temporary file; the next render
    to that folder removes it — but never one of a running process or of another host."""
    folder = tmp_path / "renders"
    code = ("import os, signal, sys; from pathlib import Path; from backend import imageio; "
            f"imageio._atomic_target(Path({str(folder / 'shot.exr')!r}), '.exr'); "
            "os.kill(os.getpid(), signal.SIGKILL)")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT)
    assert proc.returncode == -signal.SIGKILL
    (stale,) = folder.glob(".shot.lamina-tmp-*")
    from backend.imageio import _host
    live = folder / f".shot.lamina-tmp-{_host()}-{os.getppid()}-abc.exr"     # a running process
    other = folder / ".shot.lamina-tmp-otherhost-12345-abc.exr"              # another machine's
    live.write_bytes(b"")
    other.write_bytes(b"")
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(BASE))
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        assert cli.main(["render", str(path), "-o", str(folder / "shot.exr"), "--workers", "1",
                         "--progress", "none"]) == 0
    finally:
        for s, h in handlers.items():
            signal.signal(s, h)
    assert not stale.exists() and live.exists() and other.exists()
    assert (folder / "shot.exr").exists()


# --------------------------------------------------------------------------- lost workers

def layered_scene(size: int, spp: int) -> dict:
    coat = {"type": "layered", "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.1},
                                              {"type": "diffuse", "color": [0.7, 0.3, 0.2]}],
            "media": [{"thickness": 0.2, "sigma_t": 1.0, "albedo": 0.8}]}
    return scene(size, size, front_perspective(4.0, 0.3), {"m": coat},
                 {"ball": {"shape": "sphere", "radius": 1.0, "segments": 32}}, [{"mesh": "ball", "materials": ["m"]}],
                 world={"type": "constant", "color": [0.5, 0.5, 0.5], "strength": 1.0},
                 render={"spp": spp, "max_bounces": 4, "seed": 3})


@pytest.fixture(scope="module")
def layered_reference(tmp_path_factory):
    """A small layered scene and its undisturbed image (one worker)."""
    d = tmp_path_factory.mktemp("lost")
    path = d / "scene.json"
    path.write_text(json.dumps(layered_scene(40, 6)))
    ref = d / "ref.exr"
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(path), "-o", str(ref),
                           "--workers", "1", "--progress", "none"], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return path, read_exr(ref)[0]


def render_with_faults(path: Path, out: Path, faults: list[str], workers: int = 2, extra=(), start="fork",
                       parallel="processes"):
    folder = out.parent / f"faults-{out.stem}"
    folder.mkdir()
    for name in faults:
        (folder / name).write_text("")
    env = dict(os.environ, LAMINA_TEST_FAULT_DIR=str(folder), LAMINA_WORKER_START=start)
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(path), "-o", str(out),
                           "--workers", str(workers), "--parallel", parallel, "--progress", "json", *extra], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)
    events = [json.loads(ln) for ln in proc.stdout.splitlines() if ln.startswith("{")]
    return proc, events, sorted(p.name for p in folder.iterdir())


@pytest.mark.slow
@pytest.mark.parametrize("start", ["fork", "spawn"])
def test_a_killed_worker_process_loses_nothing(layered_reference, tmp_path, start):
    """SIGKILL and SIGSEGV of worker processes (``--parallel processes``; forked on Linux,
    spawned elsewhere): their items are redone by new workers, the image is bit-identical
    to an undisturbed render, and each loss is one warning; exit 0, no traceback."""
    path, reference = layered_reference
    out = tmp_path / "killed.exr"
    proc, events, left = render_with_faults(path, out, ["kill-1", "segv-2"], start=start)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert left == []                                            # both faults happened
    assert events[0]["event"] == "start" and events[0]["parallel"] == "processes"
    warnings = [e["message"] for e in events if e["event"] == "warning"]
    assert len(warnings) == 2                                    # in either order
    assert any("a worker process was lost (killed by SIGKILL" in w for w in warnings)
    assert any("a worker process was lost (killed by SIGSEGV)" in w for w in warnings)
    assert "(loss 1 of at most 3)" in warnings[0] and "(loss 2 of at most 3)" in warnings[1]
    assert all("its work item is redone by a new worker: the image is unaffected" in w for w in warnings)
    assert np.array_equal(read_exr(out)[0], reference)


@pytest.mark.slow
def test_workers_that_keep_dying_stop_the_render_with_an_error_and_a_partial_image(layered_reference, tmp_path):
    path, _ = layered_reference
    out = tmp_path / "dying.exr"
    proc, events, left = render_with_faults(path, out, [f"kill-{i}" for i in range(6)])
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    err = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert events[-1]["event"] == "error" and err == [f"error: {events[-1]['message']}"]
    assert events[-1]["message"].startswith("worker processes were lost 4 times (last: killed by SIGKILL")
    assert f"{out} holds the samples done before that" in events[-1]["message"]
    assert len([e for e in events if e["event"] == "warning"]) == 3 and len(left) in (1, 2)   # 6 faults, 4 or 5 used
    pixels, names = read_exr(out)                                # the partial image was written
    assert np.all(np.isfinite(pixels))


@pytest.mark.slow
def test_sigterm_to_the_process_group_stops_like_sigterm_to_the_parent(tmp_path):
    """What a farm manager or `timeout` does: every process of the group gets SIGTERM. The
    render stops as interrupted (exit 130), writes the samples done, no traceback, no worker
    left behind."""
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(layered_scene(40, 100000)))
    out = tmp_path / "image.exr"
    marker = f"LAMINA_TEST_MARKER_{os.getpid()}_{time.time_ns()}"
    proc = subprocess.Popen([sys.executable, "-m", "backend", "render", str(path), "-o", str(out),
                             "--workers", "2", "--progress", "json"], cwd=ROOT, start_new_session=True,
                            env=dict(os.environ, LAMINA_TEST_MARKER=marker),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    while True:
        line = proc.stdout.readline()
        assert line, proc.stderr.read()
        if json.loads(line)["event"] == "progress":
            break
    os.killpg(proc.pid, signal.SIGTERM)
    rest, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Traceback" not in err, err
    done = json.loads(rest.splitlines()[-1])
    assert done["event"] == "done" and done["interrupted"] is True
    pixels, names = read_exr(out)
    samples = pixels[:, :, names.index("samples.Y")]
    assert 0 < samples.max() < 100000 and np.all(np.isfinite(pixels))
    from test_cli_render import _processes_with_marker
    time.sleep(0.5)
    assert _processes_with_marker(marker) == []


@pytest.mark.slow
def test_worker_processes_share_the_scene(tmp_path):
    """Worker processes are forked after the scene and its BVH are built, so they share them:
    the peak memory (proportional set size of all processes, sampled) of a render with 2 worker
    processes stays within 1.5× that of 1 worker (a spawned pool was 2.3× for 3.37 M triangles;
    figures in benchmarks/worker_memory.py)."""
    from benchmarks import worker_memory as wm
    mesh = tmp_path / "grid.npz"
    wm.grid_mesh(mesh, 500)                      # 500 000 triangles
    path = tmp_path / "scene.json"
    # 160 spp: both workers render for about a second, so the memory sampler (every 50 ms,
    # slower under load) sees them alive together; at 1 spp that lasted 0.13 s, and a CI run
    # under both test lanes' load once saw it not at all.
    path.write_text(json.dumps(wm.scene(str(mesh), layered=True, spp=160)))
    one = wm.measure(path, 1, tmp_path / "one.exr", "processes")
    two = wm.measure(path, 2, tmp_path / "two.exr", "processes")
    assert two["parallel"] == "processes" and two["peak_pss_while_workers"] > 0
    assert two["peak_pss"] <= 1.5 * one["peak_pss"], (one, two)
    assert two["peak_pss_while_workers"] <= 1.5 * one["peak_pss"], (one, two)
    assert np.array_equal(read_exr(tmp_path / "one.exr")[0], read_exr(tmp_path / "two.exr")[0])


@pytest.mark.parametrize("workers", [1, 2])
def test_an_exception_in_a_worker_thread_stops_with_an_error_and_the_partial_image(tmp_path, workers):
    """Worker threads (the default; they cannot die alone): an exception in one is
    reported in one line (exit 2) and the samples merged before it are written, never lost."""
    data = scene(48, 48, front_perspective(4.0, 0.3), {"m": {"type": "diffuse", "color": 0.8}},
                 {"ball": {"shape": "sphere", "radius": 1.0, "segments": 32}}, [{"mesh": "ball", "materials": ["m"]}],
                 world={"type": "constant", "color": [0.5, 0.5, 0.5], "strength": 1.0},
                 render={"spp": 600, "max_bounces": 2, "seed": 1})
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(data))
    out = tmp_path / "t.exr"
    partial = tmp_path / "p.npy"
    proc, events, left = render_with_faults(path, out, ["raise-1"], workers=workers, parallel="threads",
                                            extra=("--partial", str(partial)))
    assert proc.returncode == 2 and left == [] and "Traceback" not in proc.stderr
    assert events[0]["parallel"] == "threads"
    # the add-on is told where the final (partial) result is, then gets the error
    assert [e["event"] for e in events[-2:]] == ["partial", "error"] and np.load(partial).shape == (48, 48, 4)
    message = events[-1]["message"]
    assert message.startswith("a render worker failed (RuntimeError: injected fault (raise-1) at work_items.py:")
    assert message.endswith(f"{out} holds the samples done before that")
    pixels, names = read_exr(out)
    samples = pixels[:, :, names.index("samples.Y")]
    assert np.all(np.isfinite(pixels)) and samples.max() < 600


def test_more_workers_than_cores_warns(run):
    n = limits.cpu_count() + 1
    code, lines, _ = run(BASE, "--workers", str(n))
    assert code == 0 and any(f"--workers {n} is more than the {n - 1} core(s)" in ln for ln in lines)


def test_geometry_that_does_not_fit_in_memory_is_refused_before_flattening(monkeypatch):
    """On a 2 GiB machine, 1000 instances of a 3968-triangle sphere (4 M triangles, ~3.3 GiB
    to flatten and trace) are refused from the counts, naming `objects`, before anything that
    size is allocated; so are meshes whose triangles alone exceed the memory."""
    monkeypatch.setattr(limits, "available_memory", lambda: 2 << 30)     # a 2 GiB machine
    many = edited(lambda d: d["meshes"].update(s={"shape": "sphere", "segments": 64}) or
                  d["objects"].extend([{"mesh": "s", "materials": ["grey"]}] * 1000))
    with pytest.raises(SceneError) as info:
        load_scene_data(many, "s.json")
    assert str(info.value).startswith("s.json: objects: the objects hold 3968001 triangles (instances "
                                      "counted), which need about 3.3 GiB of memory, this machine has 2.0 GiB")
    big = edited(lambda d: d["meshes"].update({f"s{i}": {"shape": "sphere", "segments": 1024} for i in range(3)}))
    with pytest.raises(SceneError) as info:
        load_scene_data(big, "s.json")
    assert "meshes.s2: the meshes so far hold" in str(info.value)
