"""``warmup`` sub-command (docs/cli.md): compile the render kernels into the kernel cache now, so
the first render does not pay for it — for farm nodes after an install, and for the Blender
add-on's background compile (its Preferences button and the start right after enabling).

One line when compiling starts and one when it ends, with the seconds; on a warm cache one line
saying so. ``--progress json`` prints the same as JSON events (``compiling``, ``compiled``,
``warm``) for the add-on."""
from __future__ import annotations

import json
import sys


def register(sub) -> None:
    p = sub.add_parser("warmup", help="compile the render kernels now (first run only; about a minute)")
    p.add_argument("--progress", choices=("text", "json"), default="text",
                   help="text lines (default) or JSON events, one per line")
    p.set_defaults(func=cmd_warmup)


def cmd_warmup(args) -> int:
    from ..kernels.cache import configure
    from ..warmup import ensure_compiled

    def emit(event: dict) -> None:
        if args.progress == "json":
            print(json.dumps(event), flush=True)
        else:
            print(f"Lamina: {event['message']}", file=sys.stderr, flush=True)

    seconds = ensure_compiled(emit)
    if seconds == 0.0:
        emit({"event": "warm", "message": f"render kernels are compiled (cached in {configure()})"})
    return 0
