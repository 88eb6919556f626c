"""``python -m backend ies info FILE [--json]`` and ``ies plot FILE -o OUT.png``: a photometry inspector."""
from __future__ import annotations

import json
import math

import numpy as np

from ..errors import LaminaError


def register(subparsers) -> None:
    ies = subparsers.add_parser("ies", help="inspect IES LM-63 photometric files")
    sub = ies.add_subparsers(dest="ies_command", metavar="SUBCOMMAND")
    sub.required = True

    info = sub.add_parser("info", help="format, angles, symmetry, lumens, peak, keywords")
    info.add_argument("file")
    info.add_argument("--json", action="store_true", help="machine-readable output")
    info.set_defaults(func=cmd_info)

    plot = sub.add_parser("plot", help="polar candela curves of the main planes (C0–C180 and "
                                       "C90–C270; type B: H and V planes)")
    plot.add_argument("file")
    plot.add_argument("-o", "--output", required=True, help="output image (.png, .pdf, .svg)")
    plot.add_argument("--per-klm", action="store_true",
                      help="plot cd/klm of the integrated flux instead of candela")
    plot.set_defaults(func=cmd_plot)


def _load(path: str):
    from .profile import IESProfile
    return IESProfile.from_file(path)


def _fmt(x: float | None, digits: int = 1) -> str:
    return "-" if x is None else f"{x:,.{digits}f}"


def cmd_info(args) -> int:
    profile = _load(args.file)
    s = profile.summary()
    if args.json:
        print(json.dumps(s, indent=2, ensure_ascii=False))
        return 0
    va, ha = s["vertical_angles"], s["horizontal_angles"]
    pk = s["peak"]
    lines = [
        f"file               {s['file']}",
        f"format             {s['version']}",
        f"photometric type   {s['photometric_type']}",
        f"vertical angles    {va['count']} ({va['first']:g}..{va['last']:g}°)",
        f"horizontal angles  {ha['count']} ({ha['first']:g}..{ha['last']:g}°)",
        f"symmetry           {s['symmetry']}",
        f"tilt               {s['tilt']}" + (" (parsed, not applied — as Cycles)" if s["tilt"] != "NONE" else ""),
        f"lamps              {s['lamps']} × " + ("absolute photometry (-1 lm)" if s["absolute_photometry"]
                                                 else f"{s['lumens_per_lamp']:g} lm"),
        f"candela multiplier {s['candela_multiplier']:g} (ballast factor {s['ballast_factor']:g}, "
        f"ballast-lamp factor {s['ballast_lamp_factor']:g})",
        f"lumens stated      {_fmt(s['lumens_stated'])}" + ("" if s["lumens_stated"] else " (absolute photometry)"),
        f"lumens integrated  {_fmt(s['lumens_integrated'])}"
        + (f"  (light output ratio {s['light_output_ratio']:.3f})" if s["light_output_ratio"] else ""),
        f"peak               {pk['candela']:,.1f} cd at file angles H = {pk['file_horizontal_deg']:g}°, "
        f"V = {pk['file_vertical_deg']:g}°; local direction "
        f"[{', '.join(f'{c:.3f}' for c in pk['direction_local'])}] (h = {pk['h_deg']:g}°, v = {pk['v_deg']:g}°)",
        f"input watts        {s['input_watts']:g}",
        f"units / opening    {s['units']}, {' × '.join(f'{x:g}' for x in s['luminous_opening'])}",
    ]
    if s["keywords"]:
        lines.append("keywords")
        for k, v in s["keywords"]:
            first, *more = (v or "").split("\n")
            lines.append(f"  [{k}] {first}")
            lines.extend(f"  {'':{len(k) + 2}} {m}" for m in more)
    if s["header_lines"]:
        lines.append("header text")
        lines.extend(f"  {h}" for h in s["header_lines"])
    for w in s["warnings"]:
        lines.append(f"warning: {w}")
    print("\n".join(lines))
    return 0


def plane_curves(profile, n: int = 721) -> dict:
    """Candela along the two main planes as lighting designers draw them, γ in −180..180°.

    Types C/A: the C0–C180 plane (γ = vertical angle, γ > 0 on the C0 side, 0 = nadir = local −Z)
    and the C90–C270 plane (γ > 0 on the C90 side). Type B: the horizontal plane V = 0 (γ = H)
    and the vertical plane H = 0 (γ = V), 0 = the beam axis (local −X).
    Returns {"gamma_deg": γ, label: intensity, ...} from the interpolated profile.
    """
    gamma = np.linspace(-180.0, 180.0, n)
    out = {"gamma_deg": gamma}
    if profile.source.photometric_type == 2:
        inside = np.abs(gamma) <= 90.0
        # (h, v) in the Cycles frame: h = V + 90°, v = H + 90° (see lm63.py)
        planes = {"H plane, V = 0": (np.full(n, 90.0), gamma + 90.0),
                  "V plane, H = 0": (gamma + 90.0, np.full(n, 90.0))}
        for label, (h, v) in planes.items():
            I = profile.intensity_angles(np.radians(np.clip(h, 0, 359.999)), np.radians(np.clip(v, 0, 180)))
            out[label] = np.where(inside, I, 0.0)
        return out
    v = np.radians(np.abs(gamma))
    for label, (pos, neg) in {"C0 (right) – C180 (left)": (0.0, 180.0),
                              "C90 (right) – C270 (left)": (90.0, 270.0)}.items():
        h = np.radians(np.where(gamma >= 0, pos, neg))
        out[label] = profile.intensity_angles(h, v)
    return out


def cmd_plot(args) -> int:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise LaminaError("ies plot needs matplotlib (pip install matplotlib)") from None
    from ..plot_output import check_plot_output, save_figure
    out = check_plot_output(args.output)
    profile = _load(args.file)
    curves = plane_curves(profile)
    scale, unit = 1.0, "cd"
    if args.per_klm:
        flux = profile.flux
        if flux <= 0:
            raise LaminaError(f"{args.file}: the profile emits no light; cannot plot cd/klm")
        scale, unit = 1000.0 / flux, "cd/klm"

    fig = plt.figure(figsize=(6.4, 6.8))
    ax = fig.add_subplot(projection="polar")
    ax.set_theta_zero_location("S")   # nadir / beam axis (γ = 0) at the bottom, as photometric diagrams
    ax.set_theta_direction(1)          # γ > 0 to the right (counter-clockwise from the bottom)
    g = np.radians(curves.pop("gamma_deg"))
    styles = [dict(color="tab:red", lw=1.6), dict(color="tab:blue", lw=1.4, ls="--")]
    for (label, values), style in zip(curves.items(), styles):
        ax.plot(g, values * scale, label=label, **style)
    ax.set_thetagrids(range(0, 360, 30), labels=[f"{a if a <= 180 else 360 - a}°" for a in range(0, 360, 30)])
    peak = max([float(np.max(c)) for c in curves.values()] + [1e-12]) * scale
    ax.set_rmax(_nice_ceiling(peak))
    ax.set_rlabel_position(100)
    ax.grid(True, alpha=0.4)
    src = profile.source
    title = (f"{_short(src.name)}\ntype {src.type_letter}, {src.symmetry}, "
             f"{profile.flux:,.0f} lm, peak {profile.peak['candela']:,.0f} cd")
    ax.set_title(title, fontsize=9, pad=18)
    ax.legend(loc="lower left", bbox_to_anchor=(-0.08, -0.12), fontsize=8, frameon=False)
    fig.text(0.99, 0.01, unit, ha="right", va="bottom", fontsize=8)
    try:
        save_figure(fig, out, dpi=120)
    finally:
        plt.close(fig)
    print(out)
    return 0


def _short(name: str) -> str:
    return name.replace("\\", "/").rsplit("/", 1)[-1]


def _nice_ceiling(x: float) -> float:
    e = 10.0 ** math.floor(math.log10(x))
    for m in (1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10):
        if m * e >= x:
            return m * e
    return 10 * e
