"""Child-process side of bpy_harness: load the add-on, run case functions, print results."""
from __future__ import annotations

import faulthandler
import importlib
import json
import os
import sys
import traceback

DEV_REPO = "lamina_dev"      # repository module name of an extension-mode development load


def main() -> int:
    # A crash in Blender's C code kills the runner with no Python error: print the Python stack of
    # every thread on SIGSEGV/SIGABRT so the failure says where it happened.
    faulthandler.enable(all_threads=True)
    payload = json.loads(sys.argv[1])
    import bpy  # noqa: F401  (imported first: it sets up Blender's own paths)
    if payload["dev"]:
        sys.path.insert(0, payload["dev"])
        import addon_utils
        addon_utils.enable("lamina", default_set=True, handle_error=None)
        os.environ["LAMINA_TEST_PACKAGE"] = "lamina"
    elif payload.get("repo"):
        import addon_utils
        bpy.context.preferences.extensions.repos.new(name="Lamina Dev", module=DEV_REPO,
                                                     custom_directory=payload["repo"], source="USER")
        package = f"bl_ext.{DEV_REPO}.lamina"
        addon_utils.enable(package, default_set=True, handle_error=None)
        os.environ["LAMINA_TEST_PACKAGE"] = package
    module = importlib.import_module(f"cases.{payload['module']}")
    results = {}
    for case in payload["cases"]:
        if payload["dev"] or payload.get("repo"):
            bpy.ops.wm.read_homefile(use_empty=True)
        try:
            results[case] = getattr(module, case)(payload["tmp"], **payload["args"].get(case, {}))
        except Exception:  # noqa: BLE001 - reported to pytest
            results[case] = {"error": traceback.format_exc()}
    # (a leading newline: Blender prints long reports without one at their end)
    sys.stdout.write("\nLAMINA-CASE-RESULT " + json.dumps(results) + "\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
