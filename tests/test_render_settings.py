"""The render settings' one table (backend/render_settings.py) against what reads it: the loader
takes each field with the table's default, range and choices; the ``render`` options override
the same fields within the same ranges; the kernels get the fields the table names."""
from __future__ import annotations

import copy
import subprocess
import sys

import pytest

from conftest import ROOT
from test_scene_validation import BASE, error_of

from backend.render import OPTION_SETTINGS, RenderOptions
from backend.render_settings import BY_NAME, SETTINGS, RenderSettings, kernel_values
from backend.scene.loader import load_scene_data


def with_render(**render):
    data = copy.deepcopy(BASE)
    data["render"] = render
    return data


def test_a_scene_without_render_settings_gets_the_defaults():
    s = load_scene_data(copy.deepcopy(BASE), "scene.json").settings
    for st in SETTINGS:
        assert getattr(s, st.name) == st.default, st.name
    assert isinstance(s, RenderSettings)


@pytest.mark.parametrize("st", [st for st in SETTINGS if st.kind is not str], ids=lambda st: st.name)
def test_each_number_is_read_and_held_to_its_range(st):
    inside = st.lo if st.kind is int else (st.lo + (st.hi if st.hi is not None else st.lo + 2.0)) / 2
    inside = st.kind(inside if st.name != "spp" else 7)
    s = load_scene_data(with_render(**{st.name: inside}), "scene.json").settings
    assert getattr(s, st.name) == inside
    if st.lo is not None:
        below = st.lo - 1 if st.kind is int else st.lo - 0.5
        assert f"render.{st.name}" in error_of(with_render(**{st.name: below}))
    if st.hi is not None:
        above = st.hi + 1 if st.kind is int else st.hi + 0.5
        assert f"render.{st.name}" in error_of(with_render(**{st.name: above}))


@pytest.mark.parametrize("st", [st for st in SETTINGS if st.kind is str], ids=lambda st: st.name)
def test_each_choice_takes_its_values_and_refuses_others(st):
    for value, _, _ in st.choices:
        if st.name == "missing_textures" and value == "error":
            continue                       # the test scene has no textures either way
        assert getattr(load_scene_data(with_render(**{st.name: value}), "scene.json").settings, st.name) == value
    assert f"render.{st.name}" in error_of(with_render(**{st.name: "no-such-choice"}))


def test_the_render_options_override_settings_of_the_same_name():
    import dataclasses
    fields = {f.name for f in dataclasses.fields(RenderOptions)}
    for name in OPTION_SETTINGS:
        assert name in fields and BY_NAME[name].cli, name
    scene = load_scene_data(copy.deepcopy(BASE), "scene.json")
    RenderOptions(spp=5, max_bounces=2, sampler="independent", noise_target=0.25).apply(scene)
    s = scene.settings
    assert (s.spp, s.max_bounces, s.sampler, s.noise_target) == (5, 2, "independent", 0.25)


@pytest.mark.parametrize("option,value", [("--spp", "0"), ("--max-bounces", "-1"), ("--noise-target", "1.5"),
                                          ("--min-spp", "0"), ("--time-limit", "-1"), ("--seed", "-3")])
def test_the_command_line_refuses_what_the_scene_file_refuses(tmp_path, option, value):
    st = next(s for s in SETTINGS if s.cli == option)
    scene = tmp_path / "scene.json"
    import json
    scene.write_text(json.dumps(BASE))
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(scene), "-o", str(tmp_path / "x.exr"),
                           option, value], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 2 and option in proc.stderr, proc.stderr
    lo = f"{st.lo:g}" if st.kind is float else str(st.lo)
    assert lo in proc.stderr                  # the message states the table's range


def test_the_kernels_get_the_fields_the_table_names():
    from backend.kernels.integrator import Settings
    values = kernel_values(load_scene_data(with_render(rr_depth=5, clamp=2.5, glossy_light_samples=3),
                                           "scene.json").settings)
    assert (values["rr_depth"], values["clamp"], values["glossy_light_samples"]) == (5, 2.5, 3)
    assert set(values) <= set(Settings._fields)
    assert set(values) == {st.kernel for st in SETTINGS if st.kernel}
