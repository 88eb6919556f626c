"""``session`` sub-command: the interactive renderer process (docs/session.md)."""
from __future__ import annotations

import tempfile
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("session", help="interactive renderer: JSON commands on stdin, events on stdout, "
                                       "frames as files (docs/session.md)")
    p.add_argument("--frames", help="folder for the frame files (default: a new temporary folder)")
    p.add_argument("--workers", type=int, default=0, help="render threads (default: one per core)")
    p.add_argument("--samples", type=int, default=32, help="samples per pixel before going idle (0 = no limit; "
                                                           "the 'samples' command changes it)")
    p.add_argument("--warm", action="store_true",
                   help="load every compiled kernel before the first scene arrives (for a session "
                        "started ahead of time)")
    p.set_defaults(func=cmd_session)


def cmd_session(args) -> int:
    import signal
    import sys

    from ..errors import LaminaError
    from .loop import run_session
    if args.samples < 0:
        raise LaminaError(f"--samples must be >= 0, got {args.samples}")
    folder = Path(args.frames) if args.frames else Path(tempfile.mkdtemp(prefix="lamina-session-"))
    # SIGTERM ends the process at once (nothing to save); the client may also just close stdin.
    try:
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    except (ValueError, OSError):
        pass
    return run_session(folder, args.workers, args.samples, warm=args.warm)
