"""Command-line interface: ``python -m backend <command> ...``.

Each command lives in its own module with ``register(subparsers)`` (this package's render, bsdf
and presets; ies/cli.py and session/cli.py beside the code they drive); this file only dispatches
and turns user errors into one clear line on stderr (exit status 2) — never a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from .. import __version__
from ..errors import OUT_OF_MEMORY, LaminaError

# Modules that add sub-commands. A module that is missing (work in progress) is skipped.
COMMAND_MODULES = (
    "backend.cli.render",      # render, validate
    "backend.cli.bsdf",        # bsdf albedo / eval / plot
    "backend.ies.cli",         # ies info / plot
    "backend.cli.presets",     # presets list / show
    "backend.cli.warmup",      # warmup (compile the kernels now)
    "backend.session.cli",     # session (interactive renderer, docs/session.md)
    "backend.cli.serve",       # serve (render server: many render jobs in one warm process)
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m backend",
                                     description="Lamina: a layered-material path tracer.")
    parser.add_argument("--version", action="version", version=f"Lamina {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:
                continue
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except LaminaError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print(f"error: {OUT_OF_MEMORY}", file=sys.stderr)
        return 2
