"""The BSDF inspector: ``python -m backend bsdf albedo|eval|plot``."""
import json

import numpy as np
import pytest

from backend.cli import main
from backend.materials.fresnel import dielectric as fresnel

LOSSLESS = {"type": "layered",
            "interfaces": [{"type": "dielectric", "ior": 1.5}, {"type": "dielectric", "ior": 1.0}],
            "media": [{"sigma_t": 1.0, "albedo": 1.0, "phase": {"type": "hg", "g": 0.3}}]}
FIG2 = {"type": "layered",
        "interfaces": [{"type": "dielectric", "ior": 1.5, "roughness": 0.05, "distribution": "beckmann"},
                       {"type": "conductor", "metal": "Cu", "roughness": 0.05, "distribution": "beckmann"}],
        "media": [{"sigma_t": 1.0, "albedo": [0.5, 0.7, 0.95], "phase": {"type": "hg", "g": 0.5}}]}


def write(tmp_path, name, obj):
    p = tmp_path / name
    p.write_text(json.dumps(obj))
    return str(p)


def run_json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_albedo_conserves_energy_and_reports_specular_parts(tmp_path, capsys):
    path = write(tmp_path, "lossless.json", LOSSLESS)
    res = run_json(capsys, ["bsdf", "albedo", path, "--theta", "0", "--samples", "40000", "--json"])
    assert np.allclose(np.add(res["R"], res["T"]), 1.0) and np.allclose(res["loss"], 0.0)
    # Specular parts: closed form F + (1−F)² F T²/(1 − F²T²) and (1−F)² T/(1 − F²T²), T = e^−1.
    F = float(fresnel(np.array([1.0]), 1.5)[0][0])
    T = np.exp(-1.0)
    R_d = F + (1 - F) ** 2 * F * T * T / (1 - F * F * T * T)
    T_d = (1 - F) ** 2 * T / (1 - F * F * T * T)
    for key, ref in (("R_delta", R_d), ("T_delta", T_d)):
        assert abs(res[key][0] - ref) <= 4 * res[key + "_se"][0] + 1e-9


def test_eval_reports_values_and_the_pdfs(tmp_path, capsys):
    path = write(tmp_path, "fig2.json", FIG2)
    res = run_json(capsys, ["bsdf", "eval", path, "--wi", "30,0", "--wo", "30,180", "--samples", "4000",
                            "--estimator", "uni", "--json"])
    assert res["stochastic"] and res["estimator"] == "uni" and res["samples"] == 4000
    assert all(np.isfinite(res["f_cos"])) and all(s > 0 for s in res["f_cos_se"])
    assert res["pdf_approx"] > 0 and res["pdf_stochastic"] > 0 and res["pdf_lobes"] > 0
    assert res["pdf_mis"] == "lobes" and res["pdf_lobes_se"] <= 1e-9 * res["pdf_lobes"]   # default; deterministic
    # An analytic material: one exact evaluation, standard error 0.
    gold = write(tmp_path, "gold.json", {"type": "conductor", "metal": "Au", "roughness": 0.2})
    res = run_json(capsys, ["bsdf", "eval", gold, "--wi", "20", "--wo", "40,180", "--json"])
    assert not res["stochastic"] and res["f_cos_se"] == [0.0, 0.0, 0.0]
    out = main(["bsdf", "eval", gold, "--wi", "20", "--wo", "40,180"])
    assert out == 0 and "analytic" in capsys.readouterr().out


def test_material_files_with_several_materials_and_presets(tmp_path, capsys):
    lib = write(tmp_path, "lib.json", {"materials": {"a": LOSSLESS, "b": {"type": "diffuse", "color": 0.5}}})
    assert main(["bsdf", "albedo", lib, "--theta", "10", "--samples", "1000"]) == 2
    assert "choose one with --name" in capsys.readouterr().err
    res = run_json(capsys, ["bsdf", "albedo", lib, "--name", "b", "--theta", "10", "--samples", "20000", "--json"])
    assert abs(res["R"][0] - 0.5) < 1e-12
    preset = write(tmp_path, "preset.json", {"name": "x", "material": {"type": "diffuse", "color": 0.25}})
    res = run_json(capsys, ["bsdf", "albedo", preset, "--theta", "10", "--samples", "100", "--json"])
    assert abs(res["R"][0] - 0.25) < 1e-12


def test_plot_writes_a_png(tmp_path, capsys):
    path = write(tmp_path, "fig2.json", FIG2)
    out = tmp_path / "lobes.png"
    assert main(["bsdf", "plot", path, "--theta", "30", "-o", str(out), "--samples", "20000",
                 "--resolution", "16", "--per-pixel", "2"]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_output_problems_are_reported_before_the_estimation(tmp_path, monkeypatch, capsys):
    import backend.cli.bsdf as bc
    path = write(tmp_path, "fig2.json", FIG2)
    monkeypatch.setattr(bc, "lobes", lambda *a, **k: 1 / 0)     # must not be reached
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    for out, message in [(tmp_path / "lobes.xyz", "cannot write '.xyz' plots (use one of:"),
                         (tmp_path / "none" / "lobes.png", "output folder does not exist"),
                         (tmp_path, "is a folder; give a file name"),
                         (blocker / "lobes.png", "cannot write there (Not a directory)")]:
        assert main(["bsdf", "plot", path, "--theta", "30", "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, (out, err)


@pytest.mark.parametrize("argv,message", [
    (["bsdf", "albedo", "no-such-material", "--theta", "10"], "no such material file, and unknown material preset"),
    (["bsdf", "eval", "{bad}", "--wi", "10", "--wo", "10"], "no such material file, and unknown material preset"),
    (["bsdf", "albedo", "missing.json", "--theta", "10"], "missing.json: no such material file"),
    # a mistyped preset name gets the presets it probably meant
    (["bsdf", "albedo", "carpaint-red", "--theta", "10"], "did you mean: car-paint-red"),
    (["bsdf", "albedo", "lamina-reference", "--theta", "10"], "did you mean: reference-microflake-3layer"),
])
def test_errors_are_one_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and message in err and "\n" not in err


def test_invalid_json_and_bad_angles(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["bsdf", "albedo", str(bad), "--theta", "10"]) == 2
    assert "cannot read material" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["bsdf", "eval", str(bad), "--wi", "200,0", "--wo", "10"])
