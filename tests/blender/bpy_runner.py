"""Child-process side of bpy_harness: load the add-on, run case functions, print results."""
from __future__ import annotations

import importlib
import json
import sys
import traceback


def main() -> int:
    payload = json.loads(sys.argv[1])
    import bpy  # noqa: F401  (imported first: it sets up Blender's own paths)
    if payload["dev"]:
        sys.path.insert(0, payload["dev"])
        import addon_utils
        addon_utils.enable("lamina", default_set=True, handle_error=None)
    module = importlib.import_module(f"cases.{payload['module']}")
    results = {}
    for case in payload["cases"]:
        if payload["dev"]:
            bpy.ops.wm.read_homefile(use_empty=True)
        try:
            results[case] = getattr(module, case)(payload["tmp"], **payload["args"].get(case, {}))
        except Exception:  # noqa: BLE001 - reported to pytest
            results[case] = {"error": traceback.format_exc()}
    sys.stdout.write("LAMINA-CASE-RESULT " + json.dumps(results) + "\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
