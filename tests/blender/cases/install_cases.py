"""Install the built extension zip into an isolated user folder and use it (no development load)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import bpy


def install(tmp, zip_path):
    import addon_utils
    status = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                       enable_on_install=True)
    module = "bl_ext.user_default.lamina"
    loaded = sorted(m for m in sys.modules if m.startswith(module))
    warnings = {}
    if hasattr(addon_utils, "_extensions_warnings_get"):
        warnings = {k: list(v) for k, v in addon_utils._extensions_warnings_get().items()}
    sc = bpy.context.scene
    sc.render.engine = "LAMINA"
    engine_mod = sys.modules[module + ".addon.engine.job"]
    env = engine_mod.child_environment()
    probe = subprocess.run([sys.executable, "-c",
                            "import json, backend, embreex, numpy, OpenImageIO;"
                            "print(json.dumps([backend.__file__, embreex.__file__]))"],
                           capture_output=True, text=True, env=env)
    version = subprocess.run([sys.executable, "-m", "backend", "--version"], capture_output=True, text=True,
                             env=env)
    prefs = bpy.context.preferences.addons.get(module)
    import importlib.util
    parent_embreex = importlib.util.find_spec("embreex")
    local = Path(bpy.utils.user_resource("EXTENSIONS", path=".local"))
    unpacked = sorted(str(p) for p in local.rglob("embreex/__init__.py"))
    unpacked_numba = sorted(str(p) for p in local.rglob("numba/__init__.py"))
    unpacked_llvmlite = sorted(str(p) for p in local.rglob("llvmlite/__init__.py"))
    # A render through the installed extension, in the environment its engine gives the child:
    # compiled kernels, cached in the extension's user folder.
    user_env = sys.modules[module + ".addon.launch"].user_environment()
    scene = Path(tmp) / "installed-scene.json"
    scene.write_text(json.dumps({
        "format": "lamina-scene", "version": 1, "film": {"width": 8, "height": 6},
        "camera": {"type": "perspective", "to_world": [[1, 0, 0, 0], [0, 0, -1, -4], [0, 1, 0, 0], [0, 0, 0, 1]],
                   "frame": [[0.36, 0.27, -1], [0.36, -0.27, -1], [-0.36, -0.27, -1], [-0.36, 0.27, -1]]},
        "render": {"spp": 2},
        "materials": {"m": {"type": "conductor", "metal": "Au", "roughness": 0.3}},
        "meshes": {"ball": {"shape": "sphere", "radius": 1.0, "segments": 16}},
        "objects": [{"mesh": "ball", "materials": ["m"]}],
        "world": {"type": "constant", "color": [0.5, 0.5, 0.5], "strength": 1}}))
    out = Path(tmp) / "installed.exr"
    render = subprocess.run([sys.executable, "-m", "backend", "render", str(scene), "-o", str(out),
                             "--workers", "1"], capture_output=True, text=True,
                            env=engine_mod.child_environment(user_env))
    kernel_dir = Path(user_env.get("LAMINA_KERNEL_CACHE", ""))
    parent_numba = importlib.util.find_spec("numba")
    return {"status": list(status), "loaded": loaded, "warnings": warnings, "engine": sc.render.engine,
            "ext_root": str(engine_mod.EXTENSION_ROOT), "probe": probe.stdout.strip(),
            "probe_err": probe.stderr[-2000:], "version": version.stdout.strip() + version.stderr.strip(),
            "has_prefs": prefs is not None and prefs.preferences is not None,
            "parent_embreex": parent_embreex.origin if parent_embreex else None, "unpacked": unpacked,
            "unpacked_numba": unpacked_numba, "unpacked_llvmlite": unpacked_llvmlite,
            "parent_numba": parent_numba.origin if parent_numba else None,
            "render_code": render.returncode, "render_err": render.stderr[-3000:],
            "rendered": out.exists(), "kernel_dir": str(kernel_dir),
            "kernel_files": sorted(p.name for p in kernel_dir.rglob("*.nbi")) if kernel_dir.is_dir() else [],
            "user_dir": str(Path(bpy.utils.resource_path("USER")))}
