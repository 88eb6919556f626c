"""The extension zip: built and validated by Blender's own extension CLI, installed and enabled."""
from __future__ import annotations

import json
import platform
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from bpy_harness import ROOT, requires_bpy, result_of, run_cases

pytestmark = [pytest.mark.blender, requires_bpy]


def this_platform() -> str | None:
    system = {"linux": "linux", "win32": "windows", "darwin": "macos"}.get(sys.platform)
    machine = {"x86_64": "x64", "amd64": "x64", "arm64": "arm64", "aarch64": "arm64"}.get(platform.machine().lower())
    name = f"{system}-{machine}"
    return name if name in ("linux-x64", "windows-x64", "macos-arm64") else None


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ext")
    target = this_platform()
    cmd = [sys.executable, str(ROOT / "tools" / "build_extension.py"), "--output-dir", str(tmp / "dist"),
           "--build-dir", str(tmp / "build"), "--python", f"{sys.version_info[0]}.{sys.version_info[1]}",
           "--allow-missing-wheels"]
    cmd += ["--platform", target] if target else ["--no-wheels"]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    zips = sorted((tmp / "dist").glob("lamina-*.zip"))
    assert len(zips) == 1, proc.stdout
    return tmp, zips[0], proc.stdout


def test_zip_validated_and_contents(built):
    _, path, log = built
    assert "validated" in log
    names = zipfile.ZipFile(path).namelist()
    tops = {n.split("/")[0] for n in names}
    assert {"__init__.py", "blender_manifest.toml", "addon", "backend"} <= tops
    assert not tops & {"tests", "tools", ".venv", "build", "benchmarks", ".git", "pytest.ini", "showcase", ".ci"}
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
    wheels = [n for n in names if n.endswith(".whl")]
    assert not [w for w in wheels if "numpy" in w]
    manifest = zipfile.ZipFile(path).read("blender_manifest.toml").decode()
    for w in wheels:
        assert f'"./{w}"' in manifest
    # One zip per platform and Python: this Python's wheels only, for the Blender versions that
    # bundle it (3.11: 4.2 to 5.0; 3.13: 5.1 on), named so.
    tag = f"cp{sys.version_info[0]}{sys.version_info[1]}"
    assert path.name.endswith(f"-{tag}.zip"), path.name
    assert all(f"-{tag}-" in w for w in wheels), wheels
    low, high = {"cp311": ("4.2.0", "5.1.0"), "cp313": ("5.1.0", None)}[tag]
    assert f'blender_version_min = "{low}"' in manifest
    assert (f'blender_version_max = "{high}"' in manifest) if high else ("blender_version_max" not in manifest)
    if this_platform():
        assert f'platforms = ["{this_platform()}"]' in manifest
        assert path.stat().st_size <= 90e6, path.stat().st_size            # issue 38: each zip ≤ 90 MB
    if this_platform() and "warning: no embreex wheel" not in log:
        assert any(w.startswith("wheels/embreex-") for w in wheels)


def test_installs_enables_and_finds_its_backend(built):
    tmp, path, log = built
    user = tmp / "user"
    r = result_of(run_cases("install_cases", ["install"], tmp=tmp, dev_load=False,
                            env={"BLENDER_USER_RESOURCES": str(user), "LAMINA_KERNEL_CACHE": ""},
                            args={"install": {"zip_path": str(path)}}), "install")
    assert r["status"] == ["FINISHED"]
    assert "bl_ext.user_default.lamina.addon.engine.engine" in r["loaded"]
    assert r["engine"] == "LAMINA" and r["has_prefs"]
    assert not r["warnings"], r["warnings"]                 # no sys.path / top-level policy violations
    backend_file, embreex_file = json.loads(r["probe"] or "[null, null]") if r["probe"] else (None, None)
    assert backend_file, r["probe_err"]
    installed = Path(r["ext_root"])
    assert Path(backend_file).resolve().is_relative_to(installed.resolve())
    assert installed.resolve().is_relative_to(user.resolve())
    # The child imports embreex from where Blender itself would (in a real Blender that is the
    # unpacked wheel; under the bpy module the venv's own copy comes first on sys.path).
    assert Path(embreex_file).resolve() == Path(r["parent_embreex"]).resolve()
    if any(n.endswith(".whl") for n in zipfile.ZipFile(path).namelist()):
        assert r["unpacked"] and Path(r["unpacked"][0]).resolve().is_relative_to(user.resolve())
    assert r["version"].startswith("Lamina")
    # Renders with compiled kernels, compiled once into the extension's user folder.
    assert r["render_code"] == 0 and r["rendered"], r["render_err"]
    assert "compiling render kernels (first run only)" in r["render_err"]
    assert Path(r["kernel_dir"]).resolve().is_relative_to(user.resolve()), r["kernel_dir"]
    assert r["kernel_files"], "no compiled kernel in the extension's user folder"
    if this_platform() and "warning: no numba wheel" not in log and "warning: no llvmlite wheel" not in log:
        names = zipfile.ZipFile(path).namelist()
        assert any(n.startswith("wheels/numba-") for n in names)
        assert any(n.startswith("wheels/llvmlite-") for n in names)
        assert r["unpacked_numba"] and r["unpacked_llvmlite"]


def test_backend_runs_with_blenders_own_openimageio(tmp_path):
    """Blender bundles OpenImageIO with its Python (bpy 5.0.1: 3.0.9); the backend's EXR/texture
    I/O must work with that version, since the extension does not ship its own."""
    import importlib.util
    import os
    base = Path(list(importlib.util.find_spec("bpy").submodule_search_locations)[0])
    bundled = sorted(base.glob("*/python/lib/python3*/site-packages/OpenImageIO"))
    if not bundled:
        pytest.skip("this bpy build bundles no OpenImageIO")
    site = bundled[-1].parent
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps({
        "format": "lamina-scene", "version": 1, "film": {"width": 8, "height": 6},
        "camera": {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0, -1, -4], [0, 1, 0, 0], [0, 0, 0, 1]],
                   "frame": [[0.36, 0.27, -1], [0.36, -0.27, -1], [-0.36, -0.27, -1], [-0.36, 0.27, -1]]},
        "render": {"spp": 2},
        "world": {"type": "constant", "color": [0.5, 0.5, 0.5], "strength": 1}}))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(ROOT)]))
    code = ("import OpenImageIO, runpy, sys; print('OIIO', OpenImageIO.VERSION_STRING, OpenImageIO.__file__);"
            "sys.argv = ['backend', 'render', sys.argv[1], '-o', sys.argv[2], '--workers', '1'];"
            "runpy.run_module('backend', run_name='__main__')")
    out = subprocess.run([sys.executable, "-c", code, str(scene), str(tmp_path / "o.exr")],
                         capture_output=True, text=True, env=env, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert str(site) in out.stdout
    import OpenImageIO as oiio
    img = oiio.ImageBuf(str(tmp_path / "o.exr"))
    assert img.spec().width == 8 and "albedo.R" in img.spec().channelnames
    print("\n" + out.stdout.strip().splitlines()[0])
