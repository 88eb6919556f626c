#!/usr/bin/env python3
"""Render a .blend with the Lamina engine through the bpy module, with this checkout's add-on.

    python tools/render_blend.py showcase/showcase.blend -o out/showcase_blend.png [--spp N]
                                 [--resolution 320x180] [--workers K]

What ``blender -b FILE -E LAMINA -o OUT -f 1`` does with the extension installed, for machines
with the bpy module (requirements-dev.txt) instead of a Blender install. The output format follows
the file extension (.png, .exr, .jpg). Exit status 1 if the render fails (the message is printed).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FORMATS = {".png": "PNG", ".exr": "OPEN_EXR", ".jpg": "JPEG", ".jpeg": "JPEG"}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("blend", type=Path)
    parser.add_argument("-o", "--output", type=Path, required=True, help="image file (.png, .exr, .jpg)")
    parser.add_argument("--spp", type=int, help="samples per pixel (default: the file's)")
    parser.add_argument("--resolution", help="WxH (default: the file's)")
    parser.add_argument("--workers", type=int, help="backend worker processes (default: the file's)")
    args = parser.parse_args(argv)
    fmt = FORMATS.get(args.output.suffix.lower())
    if fmt is None:
        parser.error(f"unsupported output format {args.output.suffix!r} (use {', '.join(FORMATS)})")
    if not args.blend.is_file():
        parser.error(f"{args.blend}: no such file")
    try:
        import bpy
    except ImportError:
        print("render_blend: needs the bpy module (pip install -r requirements-dev.txt)", file=sys.stderr)
        return 2
    import addon_utils
    dev = Path(tempfile.mkdtemp(prefix="lamina-dev-"))
    (dev / "lamina").symlink_to(ROOT, target_is_directory=True)
    sys.path.insert(0, str(dev))
    addon_utils.enable("lamina", default_set=True, handle_error=None)

    bpy.ops.wm.open_mainfile(filepath=str(args.blend.resolve()), load_ui=False)
    sc = bpy.context.scene
    if sc.render.engine != "LAMINA":
        print(f"render_blend: {args.blend} uses the {sc.render.engine} engine, not LAMINA", file=sys.stderr)
        return 1
    if args.spp:
        sc.lamina.samples = args.spp
    if args.workers is not None:
        sc.lamina.workers = args.workers
    if args.resolution:
        w, _, h = args.resolution.lower().partition("x")
        sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = int(w), int(h), 100
    out = args.output.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    sc.render.image_settings.file_format = fmt
    sc.render.filepath = str(out)
    sc.render.use_file_extension = False
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError as exc:               # the engine's error_set: a failed render
        print(f"render_blend: {str(exc).strip()}", file=sys.stderr)
        return 1
    if not out.is_file():
        print(f"render_blend: no image was written to {out}", file=sys.stderr)
        return 1
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
