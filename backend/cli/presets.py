"""``python -m backend presets ...``: list, show, validate the material presets; render thumbnails.

    presets list [--category C] [--tag T] [--json]
    presets show NAME [--material] [--json]
    presets validate [NAME|FILE ...] [--thumbnails] [--json]
    presets thumbnails [NAME ...] [--spp N] [--size PX] [--workers K] [--no-gallery]
    presets gallery
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..errors import LaminaError


def register(sub) -> None:
    p = sub.add_parser("presets", help="material preset library: list, show, validate, thumbnails",
                       description="The material preset library (presets/, and folders in LAMINA_PRESET_PATH). "
                                   "A preset name works anywhere a material is accepted.")
    psub = p.add_subparsers(dest="presets_command", metavar="ACTION")

    q = psub.add_parser("list", help="list the presets")
    q.add_argument("--category", help="only this category")
    q.add_argument("--tag", help="only presets with this tag")
    q.add_argument("--json", action="store_true", help="machine-readable output")
    q.set_defaults(func=cmd_list)

    q = psub.add_parser("show", help="print one preset")
    q.add_argument("name", help="preset name or preset file")
    q.add_argument("--material", action="store_true",
                   help="print only the material object (paste it into a scene's materials)")
    q.add_argument("--json", action="store_true", help="print the preset document as stored")
    q.set_defaults(func=cmd_show)

    q = psub.add_parser("validate", help="check preset files (metadata, material, loadability)")
    q.add_argument("names", nargs="*", help="preset names or files (default: every preset)")
    q.add_argument("--thumbnails", action="store_true", help="also require each preset's thumbnail")
    q.add_argument("--json", action="store_true", help="machine-readable output")
    q.set_defaults(func=cmd_validate)

    q = psub.add_parser("thumbnails", help="render preset thumbnails and rewrite docs/presets.md")
    q.add_argument("names", nargs="*", help="presets to render (default: every shipped preset)")
    q.add_argument("--spp", type=int, default=None, help="samples per pixel (default: the stage's)")
    q.add_argument("--size", type=int, default=None, help="pixels (square; default: the stage's)")
    q.add_argument("--workers", type=int, default=None, help="worker processes (default: all cores)")
    q.add_argument("--missing", action="store_true", help="only presets without a thumbnail")
    q.add_argument("--no-gallery", action="store_true", help="do not rewrite docs/presets.md")
    q.set_defaults(func=cmd_thumbnails)

    q = psub.add_parser("gallery", help="rewrite docs/presets.md from the presets and thumbnails")
    q.set_defaults(func=cmd_gallery)

    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def _info(name_or_path: str):
    from ..presets import read_preset, require_preset
    p = Path(name_or_path)
    if p.suffix.lower() == ".json" or "/" in name_or_path:
        if not p.is_file():
            raise LaminaError(f"{name_or_path}: preset file not found")
        return read_preset(p)
    return read_preset(require_preset(name_or_path))


def cmd_list(args) -> int:
    from ..presets import all_presets, describe_stack
    everything = presets = all_presets()
    if args.category:
        presets = [p for p in presets if p.category == args.category]
    if args.tag:
        presets = [p for p in presets if args.tag in p.tags]
    if args.json:
        print(json.dumps([p.summary() for p in presets], indent=1, ensure_ascii=False))
        return 0
    if not presets:
        # Say what the filters could have been: an empty list alone reads like a broken library.
        known = []
        if args.category and args.category not in {p.category for p in everything}:
            known.append("categories: " + ", ".join(sorted({p.category for p in everything})))
        if args.tag and all(args.tag not in p.tags for p in everything):
            known.append("tags: " + ", ".join(sorted({t for p in everything for t in p.tags})))
        print("no presets found" + (" (" + "; ".join(known) + ")" if known else ""))
        return 0
    width = max(len(p.name) for p in presets)
    cwidth = max(len(p.category) for p in presets)
    for p in sorted(presets, key=lambda p: (p.category, p.name)):
        print(f"{p.name:<{width}}  {p.category:<{cwidth}}  {describe_stack(p.material)}")
    print(f"{len(presets)} presets", file=sys.stderr)
    return 0


def cmd_show(args) -> int:
    from ..presets import describe_stack, dumps, load_preset_document
    info = _info(args.name)
    if args.material:
        sys.stdout.write(dumps(info.material))
        return 0
    if args.json:
        sys.stdout.write(dumps(load_preset_document(info.path)))
        return 0
    print(f"{info.label}  ({info.name}, {info.category})")
    print(f"file:        {info.path}")
    print(f"thumbnail:   {info.thumbnail if info.thumbnail.is_file() else '(none)'}")
    print(f"tags:        {', '.join(info.tags) or '-'}")
    if info.source:
        print(f"source:      {info.source}")
    print(f"stack:       {describe_stack(info.material)}")
    print()
    print(info.description)
    if info.units:
        print("\nunits:")
        for k, v in info.units.items():
            print(f"  {k}: {v}")
    print("\nmaterial:")
    sys.stdout.write(dumps(info.material))
    return 0


def validate_all(names: list[str], thumbnails: bool = False) -> list[dict]:
    """One record per preset: {"name", "path", "ok", "error", "warnings"}; also reports shadowed names."""
    from ..presets import _preset_files, check_preset, find_preset, list_presets, preset_dirs, unknown_preset_message
    if names:
        paths = []
        for n in names:
            p = Path(n)
            if p.suffix.lower() == ".json" or "/" in n:
                paths.append(p)
            else:
                found = find_preset(n)
                if found is None:
                    raise LaminaError(unknown_preset_message(n))
                paths.append(found)
    else:
        paths = list_presets()
    seen: dict[str, Path] = {}
    shadowed: dict[str, list[str]] = {}
    for folder in preset_dirs():
        for p in _preset_files(folder):
            if p.stem in seen and seen[p.stem] != p:
                shadowed.setdefault(p.stem, []).append(str(p))
            seen.setdefault(p.stem, p)
    records = []
    for path in paths:
        rec = {"name": path.stem, "path": str(path), "ok": True, "error": None, "warnings": []}
        try:
            _, warnings = check_preset(path)
            rec["warnings"] = list(warnings)
            if thumbnails and not (path.parent / "thumbnails" / f"{path.stem}.png").is_file():
                raise LaminaError(f"{path}: no thumbnail (run `python -m backend presets thumbnails {path.stem}`)")
        except LaminaError as exc:
            rec["ok"], rec["error"] = False, str(exc)
        if path.stem in shadowed:
            rec["warnings"].append(f"also defined in {', '.join(shadowed[path.stem])} (shadowed by {path})")
        records.append(rec)
    return records


def cmd_validate(args) -> int:
    records = validate_all(args.names, args.thumbnails)
    bad = [r for r in records if not r["ok"]]
    if args.json:
        print(json.dumps({"presets": records, "failed": len(bad)}, indent=1, ensure_ascii=False))
    else:
        for r in records:
            print(f"{'ok    ' if r['ok'] else 'FAILED'} {r['name']}" + (f": {r['error']}" if r["error"] else ""))
            for w in r["warnings"]:
                print(f"       warning: {w}")
        print(f"{len(records) - len(bad)} of {len(records)} presets valid", file=sys.stderr)
    return 2 if bad else 0


def cmd_thumbnails(args) -> int:
    from .. import preset_thumbnails as pt
    from ..presets import all_presets, check_preset
    if args.names:
        infos = [_info(n) for n in args.names]
    else:
        infos = [p for p in all_presets() if p.shipped]
    if args.missing:
        infos = [p for p in infos if not p.thumbnail.is_file()]
    for info in infos:   # fail before spending minutes rendering
        check_preset(info.path)
    kwargs = {"workers": args.workers}
    if args.spp:
        kwargs["spp"] = args.spp
    if args.size:
        kwargs["size"] = args.size
    for i, info in enumerate(infos, 1):
        out, seconds = pt.write_thumbnail(info, **kwargs)
        print(f"[{i}/{len(infos)}] {info.name}: {out} ({seconds:.1f} s)", flush=True)
    if not args.no_gallery:
        cmd_gallery(args)
    return 0


def cmd_gallery(args) -> int:
    from ..preset_thumbnails import GALLERY, gallery_markdown
    from ..presets import all_presets
    presets = [p for p in all_presets() if p.shipped]
    GALLERY.parent.mkdir(parents=True, exist_ok=True)
    GALLERY.write_text(gallery_markdown(presets, GALLERY), encoding="utf-8")
    print(f"wrote {GALLERY} ({len(presets)} presets)")
    return 0
