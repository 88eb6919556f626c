"""``bsdf`` sub-commands: inspect a material's BSDF (docs/bsdf-inspector.md).

    python -m backend bsdf albedo MATERIAL --theta DEG [--phi DEG] [--samples N] [--json]
    python -m backend bsdf eval MATERIAL --wi θ,φ --wo θ,φ [--estimator uni|bi] [--samples N] [--json]
    python -m backend bsdf plot MATERIAL --theta DEG -o FILE.png [--phi DEG] [--samples N]

MATERIAL is a material JSON file (an object with "type"; a scene or library file with
"materials" — pick one with ``--name`` —; or a preset file with "material"), or a preset name.
Angles in degrees: θ from the surface normal (θ > 90° is below the surface), φ from the UV
tangent. Values are per linear RGB channel with their standard errors (Monte Carlo: layered
BSDFs are estimated stochastically; analytic ones are exact and report 0).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from ..errors import LaminaError
from ..plot_output import check_plot_output, save_figure


# ----------------------------------------------------------------------------- material lookup
def resolve_material(name_or_path: str, name: str | None = None, defaults: dict | None = None):
    """A Material from a file path or a preset name (the one place the inspector resolves names)."""
    from ..materials import load_all
    from ..scene.reader import LoadContext, Node, dispatch

    path = Path(name_or_path)
    if not path.is_file():
        from ..presets import find_preset, unknown_preset_message
        found = find_preset(name_or_path) if not path.suffix else None
        if found is None:
            if path.suffix:
                raise LaminaError(f"{name_or_path}: no such material file")
            raise LaminaError(f"{name_or_path}: no such material file, and {unknown_preset_message(name_or_path)}")
        path = found
    from ..scene.reader import read_json
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise LaminaError(f"{path}: cannot read material: {exc}") from None
    from ..errors import SceneError
    try:
        data = read_json(text, str(path))
    except SceneError as exc:
        raise LaminaError(f"{path}: cannot read material: {exc.message}") from None
    ctx = LoadContext(str(path), path.parent)
    node_path = ""
    if isinstance(data, dict) and "type" in data:
        value = data
    elif isinstance(data, dict) and isinstance(data.get("material"), dict):
        value, node_path = data["material"], "material"          # a preset file
    elif isinstance(data, dict) and isinstance(data.get("materials"), dict):
        mats = data["materials"]
        if name is None:
            if len(mats) != 1:
                raise LaminaError(f"{path}: holds {len(mats)} materials ({', '.join(mats)}); "
                                  "choose one with --name")
            name = next(iter(mats))
        if name not in mats:
            raise LaminaError(f"{path}: no material {name!r} (known: {', '.join(mats)})")
        value, node_path = mats[name], f"materials.{name}"
        layered = data.get("render", {}).get("layered") if isinstance(data.get("render"), dict) else None
        if isinstance(layered, dict):
            defaults = {**layered, **(defaults or {})}
    else:
        raise LaminaError(f"{path}: expected a material object with \"type\", a preset file "
                          "with \"material\", or a file with \"materials\"")
    ctx.cache["layered_defaults"] = defaults or {}
    if isinstance(value, str):
        from ..presets import resolve_preset
        return resolve_preset(value, Node(value, node_path, ctx))
    return dispatch(Node(value, node_path, ctx), load_all())


# ----------------------------------------------------------------------------- helpers
def direction(theta_deg: float, phi_deg: float) -> np.ndarray:
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def _angles(text: str):
    try:
        parts = [float(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected θ,φ in degrees, got {text!r}") from None
    if len(parts) == 1:
        parts.append(0.0)
    if len(parts) != 2 or not 0.0 <= parts[0] <= 180.0:
        raise argparse.ArgumentTypeError(f"expected θ,φ in degrees with 0 <= θ <= 180, got {text!r}")
    return parts


def _theta(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an angle in degrees, got {text!r}") from None
    if not 0.0 <= v <= 180.0:
        raise argparse.ArgumentTypeError(f"expected 0 <= θ <= 180 degrees, got {text!r}")
    return v


def _count(text: str) -> int:
    try:
        v = int(float(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a sample count, got {text!r}") from None
    if v < 2:
        raise argparse.ArgumentTypeError(f"expected at least 2 samples, got {text!r}")
    return v


def _uv(text: str):
    try:
        u, v = (float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected u,v, got {text!r}") from None
    return u, v


def _bind(material, n: int, uv):
    from ..materials.base import ShadingContext
    return material.bind(ShadingContext(np.tile(np.asarray(uv, dtype=np.float64), (n, 1))))


def _mean_se(x: np.ndarray):
    return x.mean(axis=0), x.std(axis=0, ddof=1) / np.sqrt(x.shape[0])


def _batched(fn, n: int, batch: int = 1 << 16):
    """Concatenate fn(k) over batches of k lanes (bounds memory for large sample counts)."""
    parts = []
    for start in range(0, n, batch):
        parts.append(fn(min(batch, n - start)))
    return [np.concatenate(p) for p in zip(*parts)]


def _fmt_rgb(mean, se):
    return "  ".join(f"{m:.5f} ± {s:.5f}" for m, s in zip(mean, se))


# ----------------------------------------------------------------------------- albedo
def albedo(material, theta: float, phi: float, samples: int, seed: int, uv=(0.5, 0.5)) -> dict:
    """Directional reflectance R and transmittance T (f·|cos| integrated over each hemisphere,
    delta lobes included) per RGB channel with standard errors, from forward samples
    (importance transport: fractions of the incident flux)."""
    from ..materials.base import IMPORTANCE
    rng = np.random.default_rng(seed)
    wi1 = direction(theta, phi)

    def run(k):
        b = _bind(material, k, uv)
        s = b.sample(np.tile(wi1, (k, 1)), rng, IMPORTANCE, **({"want_pdf": False} if b.stochastic else {}))
        same = (s.wo[:, 2] * wi1[2]) > 0
        w = np.where(np.isfinite(s.weight), s.weight, 0.0)
        return (w * same[:, None], w * ~same[:, None], w * (same & s.delta)[:, None],
                w * (~same & s.delta)[:, None])

    R, T, Rd, Td = _batched(run, samples)
    out = {"theta": theta, "phi": phi, "samples": samples}
    for key, x in (("R", R), ("T", T), ("R_delta", Rd), ("T_delta", Td)):
        m, s = _mean_se(x)
        out[key], out[key + "_se"] = m.tolist(), s.tolist()
    tot = R + T
    m, s = _mean_se(tot)
    out["loss"], out["loss_se"] = (1.0 - m).tolist(), s.tolist()
    return out


def cmd_albedo(args) -> int:
    mat = resolve_material(args.material, args.name)
    res = albedo(mat, args.theta, args.phi, args.samples, args.seed, args.uv)
    if args.json:
        print(json.dumps(res))
        return 0
    print(f"{args.material}: incident θ={args.theta:g}° φ={args.phi:g}°, {args.samples} samples (R G B ± standard error)")
    for key, label in (("R", "reflectance R"), ("T", "transmittance T"), ("R_delta", "  of which specular R"),
                       ("T_delta", "  of which specular T"), ("loss", "absorbed/lost 1 − R − T")):
        print(f"  {label:24s} {_fmt_rgb(res[key], res[key + '_se'])}")
    return 0


# ----------------------------------------------------------------------------- eval
def evaluate(material, wi_angles, wo_angles, samples: int, seed: int, estimator=None, uv=(0.5, 0.5)) -> dict:
    """f(ωi, ωo)·|cos θo| (radiance transport, what the renderer uses) and the pdfs."""
    from ..materials.base import RADIANCE
    rng = np.random.default_rng(seed)
    wi1, wo1 = direction(*wi_angles), direction(*wo_angles)
    probe = _bind(material, 1, uv)
    stochastic = bool(getattr(probe, "stochastic", False))
    n = samples if stochastic else 1

    def run(k):
        b = _bind(material, k, uv)
        a, c = np.tile(wi1, (k, 1)), np.tile(wo1, (k, 1))
        kw = {"estimator": estimator} if stochastic and estimator else {}
        f = b.eval(a, c, rng, RADIANCE, **kw)
        if stochastic:
            pl = b.pdf(a, c, rng, RADIANCE, kind="lobes")
            pa = b.pdf(a, c, rng, RADIANCE, kind="approx")
            ps = b.pdf(a, c, rng, RADIANCE, kind="stochastic")
        else:
            pl = pa = ps = b.pdf(a, c, rng, RADIANCE)
        return f, pl[:, None], pa[:, None], ps[:, None]

    f, pl, pa, ps = _batched(run, n)
    out = {"wi": list(wi_angles), "wo": list(wo_angles), "samples": n, "stochastic": stochastic}
    if stochastic:
        out["estimator"] = estimator or probe.options.estimator
        out["pdf_mis"] = probe.options.pdf          # the density the material's MIS weights use
    pdf_keys = ("pdf_lobes", "pdf_approx", "pdf_stochastic")
    for key, x in (("f_cos", f), ("pdf_lobes", pl), ("pdf_approx", pa), ("pdf_stochastic", ps)):
        if x.shape[0] > 1:
            m, s = _mean_se(x)
        else:
            m, s = x[0], np.zeros(x.shape[1])
        out[key], out[key + "_se"] = m.tolist(), s.tolist()
    for key in pdf_keys + tuple(k + "_se" for k in pdf_keys):
        out[key] = out[key][0]
    return out


def _walk_defaults(args):
    """--estimator bi|uni asks for the random walk: a scene-level default the material's own
    options still override (a stack with a closed form takes it only under "auto")."""
    return {"estimator": args.estimator} if getattr(args, "estimator", None) else None


def cmd_eval(args) -> int:
    mat = resolve_material(args.material, args.name, _walk_defaults(args))
    res = evaluate(mat, args.wi, args.wo, args.samples, args.seed, args.estimator, args.uv)
    if args.json:
        print(json.dumps(res))
        return 0
    est = f", {res['estimator']} estimator" if res["stochastic"] else " (analytic)"
    print(f"{args.material}: ωi θ,φ = {args.wi[0]:g}°,{args.wi[1]:g}°  ωo = {args.wo[0]:g}°,{args.wo[1]:g}°  "
          f"{res['samples']} estimates{est}")
    print(f"  f·|cos θo| (R G B)      {_fmt_rgb(res['f_cos'], res['f_cos_se'])}")
    if res["stochastic"]:
        # MIS densities: the one the material uses is marked; lobes is deterministic.
        for kind, label in (("lobes", "lobes"), ("approx", "approximate"), ("stochastic", "stochastic")):
            mark = "  ← this material's MIS density" if res["pdf_mis"] == kind else ""
            print(f"  pdf, {label:18s} {res['pdf_' + kind]:.5f} ± {res['pdf_' + kind + '_se']:.5f}  (sr⁻¹){mark}")
    else:
        print(f"  pdf                     {res['pdf_approx']:.5f}  (sr⁻¹)")
    return 0


# ----------------------------------------------------------------------------- plot
def lobes(material, theta: float, phi: float, samples: int, seed: int, resolution: int = 48,
          per_pixel: int = 16, estimator=None, uv=(0.5, 0.5)) -> dict:
    """Hemisphere images (on the projected unit disk, x right = φ 0°) of eval, the sample
    histogram and both pdfs, for the reflection side and (transmissive materials) the other
    side, plus the in-plane slice through the plane of incidence."""
    from ..materials.base import IMPORTANCE
    rng = np.random.default_rng(seed)
    wi1 = direction(theta, phi)
    probe = _bind(material, 1, uv)
    stochastic = bool(getattr(probe, "stochastic", False))
    transmissive = bool(getattr(probe, "transmissive", False))
    # The MIS density the material uses, drawn next to the stochastic one (an approximate one if
    # the material's own is the stochastic estimate).
    mis_kind = probe.options.pdf if stochastic and probe.options.pdf != "stochastic" else "approx"
    sides = (1.0, -1.0) if transmissive else (1.0,)
    side_wi = 1.0 if wi1[2] >= 0 else -1.0
    r = resolution
    xs = (np.arange(r) + 0.5) / r * 2 - 1
    X, Y = np.meshgrid(xs, -xs)
    inside = X * X + Y * Y < 1.0
    Z = np.sqrt(np.maximum(0.0, 1 - X * X - Y * Y))
    kw = {"estimator": estimator} if stochastic and estimator else {}
    images = {}
    # Forward samples → histogram of f·|cos| per pixel (per unit solid angle).
    s = _batched(lambda k: (lambda smp: (smp.wo, smp.weight, smp.delta[:, None] * 1.0))(
        _bind(material, k, uv).sample(np.tile(wi1, (k, 1)), rng, IMPORTANCE,
                                      **({"want_pdf": False} if stochastic else {}))), samples)
    wo_s, w_s, dl = s
    w_s = np.where(dl > 0, 0.0, w_s)  # delta lobes have no density; reported by `albedo`
    reps = per_pixel if stochastic else 1
    for side in sides:
        z = side * side_wi
        dirs = np.stack([X[inside], Y[inside], z * Z[inside]], axis=1)
        m = dirs.shape[0]
        a = np.tile(wi1, (m * reps, 1))
        c = np.repeat(dirs, reps, axis=0)
        b = _bind(material, m * reps, uv)
        f = b.eval(a, c, rng, IMPORTANCE, **kw).reshape(m, reps, 3).mean(axis=1)
        if stochastic:
            pa = b.pdf(a, c, rng, kind=mis_kind).reshape(m, reps).mean(axis=1)
            ps = b.pdf(a, c, rng, kind="stochastic").reshape(m, reps).mean(axis=1)
        else:
            pa = ps = b.pdf(a, c, rng).reshape(m, reps).mean(axis=1)
        on = (wo_s[:, 2] * z) > 0
        ix = np.clip(((wo_s[on, 0] + 1) / 2 * r).astype(int), 0, r - 1)
        iy = np.clip(((1 - wo_s[on, 1]) / 2 * r).astype(int), 0, r - 1)
        hist = np.zeros((r, r, 3))
        for ch in range(3):
            np.add.at(hist[:, :, ch], (iy, ix), w_s[on, ch])
        pix = (2.0 / r) ** 2
        hist = hist / (samples * pix) * Z[:, :, None]      # → f·|cos| (dω = dx dy / cos θ)
        img = {}
        for key, v, ch in (("eval", f, 3), ("pdf_mis", pa, 1), ("pdf_stochastic", ps, 1)):
            full = np.zeros((r, r, ch))
            full[inside] = v.reshape(m, ch)
            img[key] = full
        img["histogram"] = np.where(inside[:, :, None], hist, 0.0)
        images["reflection" if side > 0 else "transmission"] = img
    # In-plane slice (plane of incidence): θo from −90° to 90° on each side.
    angles = np.linspace(-89.0, 89.0, 90)
    cp, sp = np.cos(np.radians(phi)), np.sin(np.radians(phi))
    slices = {}
    for side in sides:
        z = side * side_wi
        t = np.radians(angles)
        dirs = np.stack([np.sin(t) * cp, np.sin(t) * sp, z * np.cos(t)], axis=1)
        reps2 = 4 * per_pixel if stochastic else 1
        m = dirs.shape[0]
        b = _bind(material, m * reps2, uv)
        f = b.eval(np.tile(wi1, (m * reps2, 1)), np.repeat(dirs, reps2, axis=0), rng, IMPORTANCE, **kw)
        f = f.reshape(m, reps2, 3)
        slices["reflection" if side > 0 else "transmission"] = (
            angles, f.mean(axis=1), f.std(axis=1) / np.sqrt(max(reps2 - 1, 1)))
    return {"images": images, "slices": slices, "stochastic": stochastic, "mis_kind": mis_kind}


def cmd_plot(args) -> int:
    mat = resolve_material(args.material, args.name, _walk_defaults(args))
    out = check_plot_output(args.output)
    data = lobes(mat, args.theta, args.phi, args.samples, args.seed, args.resolution, args.per_pixel,
                 args.estimator, args.uv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sides = list(data["images"])
    fig = plt.figure(figsize=(15, 3.6 * len(sides) + 3.2))
    gs = fig.add_gridspec(len(sides) + 1, 4, height_ratios=[1.0] * len(sides) + [0.9])
    lum = np.array([0.2126, 0.7152, 0.0722])
    for row, side in enumerate(sides):
        img = data["images"][side]
        # A robust common scale per row (stochastic estimates have rare large pixels).
        fmax = max(float(np.percentile(np.concatenate([(img["eval"] @ lum).ravel(),
                                                       (img["histogram"] @ lum).ravel()]), 99.5)), 1e-12)
        pmax = max(float(np.percentile(np.concatenate([img["pdf_mis"].ravel(),
                                                       img["pdf_stochastic"].ravel()]), 99.5)), 1e-12)
        panels = (("eval", "eval f·|cos θo|", fmax), ("histogram", "sample histogram", fmax),
                  ("pdf_mis", f"pdf ({data['mis_kind']}, MIS)", pmax), ("pdf_stochastic", "pdf (stochastic)", pmax))
        for col, (key, title, vmax) in enumerate(panels):
            ax = fig.add_subplot(gs[row, col])
            v = img[key] @ lum if img[key].shape[2] == 3 else img[key][:, :, 0]
            # log(1 + x) display, as in Guo et al.'s lobe figures; common scale per row pair.
            ax.imshow(np.log1p(np.maximum(v, 0.0) / vmax * 100.0), cmap="inferno", vmin=0.0,
                      vmax=np.log1p(100.0), extent=(-1, 1, -1, 1))
            ax.set_title(f"{side}: {title}", fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    ax = fig.add_subplot(gs[len(sides), :], projection="polar")
    colors = ("tab:red", "tab:green", "tab:blue")
    for side, (ang, mean, se) in data["slices"].items():
        for ch in range(3):
            rad = np.radians(ang) if side == "reflection" else np.pi - np.radians(ang)
            ax.plot(rad, mean[:, ch], color=colors[ch], lw=1.2, ls="-" if side == "reflection" else "--")
    ax.set_theta_zero_location("N")
    ax.set_title(f"in-plane f·|cos θo| (solid: reflection, dashed: transmission), θi = {args.theta:g}°",
                 fontsize=9)
    fig.suptitle(f"{args.material} — incident θ={args.theta:g}°, φ={args.phi:g}°", fontsize=11)
    save_figure(fig, out, dpi=100)
    plt.close(fig)
    print(f"wrote {out}")
    return 0


# ----------------------------------------------------------------------------- parser
def register(sub) -> None:
    p = sub.add_parser("bsdf", help="inspect a material's BSDF: albedo, eval, lobe plots")
    bs = p.add_subparsers(dest="bsdf_command", metavar="ACTION")

    def common(q, samples):
        q.add_argument("material", help="material JSON file or preset name")
        q.add_argument("--name", help="material name inside a file with \"materials\"")
        q.add_argument("--samples", type=_count, default=samples, help=f"sample count (default {samples})")
        q.add_argument("--seed", type=int, default=0)
        q.add_argument("--uv", type=_uv, default=(0.5, 0.5), help="texture coordinates (default 0.5,0.5)")

    a = bs.add_parser("albedo", help="directional reflectance and transmittance per RGB channel")
    common(a, 200_000)
    a.add_argument("--theta", type=_theta, required=True, help="incident polar angle in degrees")
    a.add_argument("--phi", type=float, default=0.0, help="incident azimuth in degrees")
    a.add_argument("--json", action="store_true")
    a.set_defaults(func=cmd_albedo)

    e = bs.add_parser("eval", help="f(ωi,ωo)·|cos θo| and the pdfs, with standard errors")
    common(e, 20_000)
    e.add_argument("--wi", type=_angles, required=True, help="θ,φ of ωi in degrees")
    e.add_argument("--wo", type=_angles, required=True, help="θ,φ of ωo in degrees")
    e.add_argument("--estimator", choices=("uni", "bi"),
                   help="evaluate a layered material with this random-walk estimator (default: the "
                        "material's; \"auto\" takes a closed form where the stack has one)")
    e.add_argument("--json", action="store_true")
    e.set_defaults(func=cmd_eval)

    g = bs.add_parser("plot", help="lobe plots: in-plane slice and hemisphere images")
    common(g, 200_000)
    g.add_argument("--theta", type=_theta, required=True)
    g.add_argument("--phi", type=float, default=0.0)
    g.add_argument("-o", "--output", required=True, help="PNG file")
    g.add_argument("--resolution", type=int, default=48, help="hemisphere image size in pixels")
    g.add_argument("--per-pixel", type=int, default=16, help="eval/pdf estimates per pixel")
    g.add_argument("--estimator", choices=("uni", "bi"))
    g.set_defaults(func=cmd_plot)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])
