"""``render`` and ``validate`` sub-commands (docs/cli.md): their arguments, and ``render``'s
dispatch to one scene (render_one.py) or the frames of an animation (frames.py)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..errors import LaminaError
from ..limits import MAX_FILM_SIDE, MAX_WORKERS
from ..render_settings import BY_NAME
from .render_one import ProgressPrinter, render_scene


def register(sub) -> None:
    p = sub.add_parser("render", help="render a scene to an EXR (and optional PNG preview)")
    p.add_argument("scene", nargs="+", help="scene description (.json), see docs/scene-format.md; "
                   "several: the frames of an animation (-o then needs #### for the frame number)")
    p.add_argument("-o", "--output", required=True, help="output EXR path")
    p.add_argument("--png", help="also write a display preview (PNG/JPEG, sRGB)")
    p.add_argument("--spp", type=_setting("spp"), help="samples per pixel (overrides the scene)")
    p.add_argument("--seed", type=_setting("seed"), help="random seed (overrides the scene)")
    p.add_argument("--sampler", choices=[c[0] for c in BY_NAME["sampler"].choices],
                   help="path sampler (overrides the scene; default sobol: scrambled Sobol points)")
    p.add_argument("--workers", type=_int_in(1, MAX_WORKERS), help="parallel workers (default: all cores)")
    p.add_argument("--parallel", choices=("threads", "processes"),
                   help="kind of worker (default threads; processes: a crashed worker loses nothing)")
    p.add_argument("--cluster", type=_cluster_address, metavar="ADDRESS",
                   help="render the work items on a Dask cluster: its scheduler (tcp://HOST:8786) or "
                        "local:N (a local cluster of N worker processes); needs `distributed`, docs/cluster.md")
    p.add_argument("--cluster-files", choices=("send", "shared"), default="send",
                   help="with --cluster: send the scene's files to the workers (content-hashed, "
                        "cached there; default), or 'shared': the workers read the same paths")
    p.add_argument("--cluster-timeout", type=_number(0.1), metavar="SECONDS",
                   help="with --cluster: seconds to reach the scheduler and its first worker, and to wait for a lost scheduler connection to come back (default 10)")
    p.add_argument("--max-bounces", type=_setting("max_bounces"), help="Cycles-style max bounces")
    p.add_argument("--time-limit", type=_setting("time_limit"), help="seconds (0 = none); stop after this time, never before the first full pass")
    p.add_argument("--noise-target", type=_setting("noise_target"), help="adaptive sampling: relative error target (0 = off)")
    p.add_argument("--min-spp", type=_setting("min_spp"), help="adaptive sampling: samples before a pixel may stop")
    p.add_argument("--resolution", type=_resolution, help="WxH, overrides the film size")
    p.add_argument("--progress", choices=("bar", "json", "none"), default=None,
                   help="progress display (default: bar on a terminal, none otherwise)")
    p.add_argument("--partial", help="write partial results to this .npy path (add-on protocol)")
    p.add_argument("--partial-interval", type=_number(0.0), default=2.0, help="seconds between partial results")
    p.add_argument("--half", action="store_true", help="write half-float EXR")
    p.add_argument("--denoise", action="store_true",
                   help="denoise the finished image with Intel Open Image Denoise (pyoidn, optional: "
                        "requirements-denoise.txt), fed with the albedo and normal; the EXR's layer "
                        "'noisy' keeps the image as rendered")
    p.add_argument("--strict", action="store_true",
                   help="an image texture that cannot be read is an error (default: rendered magenta "
                        "with a warning, as in Cycles); for farms")
    p.add_argument("--view", metavar="NAME",
                   help="render the camera of this view of the scene's 'views' (a stereo eye, a "
                        "multi-view camera) instead of 'camera'")
    p.set_defaults(func=cmd_render)

    v = sub.add_parser("validate", help="load and check a scene, print warnings and a summary")
    v.add_argument("scene")
    v.add_argument("--json", action="store_true")
    v.add_argument("--strict", action="store_true", help="an image texture that cannot be read is an error")
    v.set_defaults(func=cmd_validate)


def _setting(name: str):
    """An argparse type for the option that overrides render setting ``name``: its type and
    range as the scene file has them (backend/render_settings.py)."""
    st = BY_NAME[name]
    return _int_in(st.lo, st.hi) if st.kind is int else _number(st.lo, st.hi)


def _int_in(lo: int, hi: int):
    """An argparse type: an integer in [lo, hi] (the scene format's range for the same field)."""
    import argparse

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not lo <= value <= hi:
            shown = text if len(text) <= 30 else f"{text[:27]}... ({len(text)} characters)"
            raise argparse.ArgumentTypeError(f"expected an integer in [{lo}, {hi}], got {shown!r}")
        return value
    return parse


def _number(lo: float, hi: float | None = None):
    """An argparse type: a finite float in [lo, hi] (the same ranges as the scene's fields)."""
    import argparse
    import math

    span = f"in [{lo:g}, {hi:g}]" if hi is not None else f">= {lo:g}"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number {span}, got {text!r}") from None
        if not math.isfinite(value) or value < lo or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"expected a number {span}, got {text!r}")
        return value
    return parse


def _cluster_address(text: str) -> str:
    import argparse
    from ..cluster import parse_address
    try:
        return parse_address(text)
    except LaminaError as exc:
        raise argparse.ArgumentTypeError(str(exc).split(": ", 1)[-1]) from None


MAX_FILM = MAX_FILM_SIDE   # pixels per side, as film.width/height in the scene format


def _resolution(text: str) -> tuple[int, int]:
    import argparse
    try:
        w, h = (int(v) for v in text.lower().split("x"))
        if not (1 <= w <= MAX_FILM and 1 <= h <= MAX_FILM):
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WxH such as 640x480 (1 to {MAX_FILM} each), got {text!r}") from None
    return w, h


def cmd_render(args) -> int:
    mode = args.progress or ("bar" if sys.stderr.isatty() else "none")
    return render_job(args, ProgressPrinter(mode))


def render_job(args, printer, on_renderer=None) -> int:
    """``render`` with its parsed arguments, events to ``printer``; ``on_renderer`` as in
    render_one.render_scene (the render server, serve.py, passes its cancel hook there)."""
    mode = printer.mode
    if args.denoise:
        from ..denoise import available
        problem = available()
        if problem is not None:           # one line, before the render; the image stays noisy
            printer.emit({"event": "warning", "message": f"{problem}: the image is written without denoising"})
            args.denoise = False
    if len(args.scene) > 1:
        from .frames import render_frames
        return render_frames(args, printer)
    output = Path(args.output)
    try:
        if args.cluster:
            from ..cluster import require_distributed
            require_distributed()          # before loading the scene: one clear line if missing
        return render_scene(args, Path(args.scene[0]), output, args.png, printer, on_renderer=on_renderer)
    except LaminaError as exc:
        if mode == "json":
            printer.emit({"event": "error", "message": str(exc)})
        raise


def cmd_validate(args) -> int:
    from ..scene.loader import load_scene
    from ..scene.reader import MISSING_TEXTURES
    strict = MISSING_TEXTURES.set("error" if args.strict else None)
    try:
        scene = load_scene(args.scene)
    finally:
        MISSING_TEXTURES.reset(strict)
    info = {"scene": str(args.scene), "width": scene.width, "height": scene.height,
            "triangles": scene.soup.count, "materials": scene.material_names,
            "lights": [type(l).__name__ for l in scene.lights], "spp": scene.settings.spp,
            "warnings": scene.warnings}
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        for w in scene.warnings:
            print(f"warning: {w}", file=sys.stderr)
        print(f"{args.scene}: OK — {scene.width}×{scene.height}, {scene.soup.count} triangles, "
              f"{len(scene.materials)} materials, {len(scene.lights)} lights, {scene.settings.spp} spp")
    return 0
