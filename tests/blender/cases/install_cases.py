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
    return {"status": list(status), "loaded": loaded, "warnings": warnings, "engine": sc.render.engine,
            "ext_root": str(engine_mod.EXTENSION_ROOT), "probe": probe.stdout.strip(),
            "probe_err": probe.stderr[-2000:], "version": version.stdout.strip() + version.stderr.strip(),
            "has_prefs": prefs is not None and prefs.preferences is not None,
            "parent_embreex": parent_embreex.origin if parent_embreex else None, "unpacked": unpacked,
            "user_dir": str(Path(bpy.utils.resource_path("USER")))}
