"""Preset thumbnails and the preset gallery page, rendered by Lamina itself.

Every thumbnail uses the same stage (``stage_scene``): a unit sphere with the preset's material on
a grey checker floor, lit only by an equirectangular studio environment (presets/stage/, made by
tools/gen_preset_assets.py), seen by the same camera, at the same size and sample count. So the
thumbnails compare materials, not set-ups. ``python -m backend presets thumbnails`` renders them
into ``<preset folder>/thumbnails/<name>.png`` and rewrites docs/presets.md.

Thumbnails are previews: indirect light is clamped and the image is smoothed by a small
edge-preserving filter (``smooth_preview``) guided by the render's own albedo and normal passes
and per-pixel variance, so 64 samples per pixel give a clean icon. Renders made for any other
purpose are never filtered.
"""
from __future__ import annotations

import copy
import time
from pathlib import Path

import numpy as np

from .presets import SHIPPED, PresetInfo, describe_stack

STAGE = SHIPPED / "stage"
SIZE = 128             # pixels (square)
SPP = 64               # samples per pixel of the committed thumbnails (then smoothed)
MAX_BOUNCES = 8        # enough for a 3-slab stack seen through glass
SEED = 7
CLAMP = 10.0           # clamp indirect sample values (a preview: fireflies matter more than bias)
GALLERY = SHIPPED.parent / "docs" / "presets.md"

# Camera: from the front (−Y), a little above, looking at the sphere's centre. Metres.
EYE = np.array([0.0, -4.5, 2.45])
TARGET = np.array([0.0, 0.0, 0.85])
HALF_FRAME = 0.34      # image-plane half size at distance 1: the sphere fills ≈ 60 % of the height


def look_at(eye: np.ndarray, target: np.ndarray, up=(0.0, 0.0, 1.0)) -> list:
    """Blender-style camera matrix: the camera looks down its local −Z, local +Y is up."""
    f = target - eye
    f = f / np.linalg.norm(f)
    right = np.cross(f, up)
    right = right / np.linalg.norm(right)
    cam_up = np.cross(right, f)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, cam_up, -f, eye
    return m.tolist()


def absolute_textures(material, base_dir: Path):
    """A copy of a material dict whose texture paths are absolute (resolved against base_dir)."""
    def walk(v):
        if isinstance(v, dict):
            out = {k: walk(x) for k, x in v.items()}
            tex = out.get("texture")
            if isinstance(tex, str) and not Path(tex).is_absolute():
                out["texture"] = str((base_dir / tex).resolve())
            return out
        if isinstance(v, list):
            return [walk(x) for x in v]
        return v
    return walk(copy.deepcopy(material))


FLOOR_HALF = 100.0     # metres: the floor reaches the horizon
CHECKER = 2.0 / 3.0    # metres per checker square (the texture holds 2 × 2 squares)


def floor_mesh() -> dict:
    """A large square at z = 0 whose UVs repeat the 2 × 2 checker tile every 2·CHECKER metres."""
    h = FLOOR_HALF
    t = 2 * h / (2 * CHECKER)
    return {"positions": [[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]],
            "indices": [[0, 1, 2], [0, 2, 3]],
            "uvs": [[0, 0], [t, 0], [t, t], [0, t]]}


def stage_scene(material: dict, size: int = SIZE, spp: int = SPP, seed: int = SEED) -> dict:
    """The thumbnail scene around ``material`` (a material dict with absolute texture paths)."""
    h = HALF_FRAME
    rz90 = [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 1.0], [0, 0, 0, 1]]   # texture seam to the back
    return {
        "format": "lamina-scene", "version": 1,
        "_comment": "Lamina preset thumbnail stage (backend/preset_thumbnails.py)",
        "film": {"width": size, "height": size},
        "camera": {"type": "perspective", "to_world": look_at(EYE, TARGET),
                   "frame": [[h, h, -1], [h, -h, -1], [-h, -h, -1], [-h, h, -1]]},
        "render": {"spp": spp, "max_bounces": MAX_BOUNCES, "seed": seed, "clamp": CLAMP},
        "materials": {
            "preset": material,
            "floor": {"type": "diffuse", "color": {"texture": str(STAGE / "checker.png")}},
        },
        "meshes": {"ball": {"shape": "sphere", "radius": 1.0, "segments": 96},
                   "floor": floor_mesh()},
        "objects": [{"name": "ball", "mesh": "ball", "to_world": rz90, "materials": ["preset"]},
                    {"name": "floor", "mesh": "floor", "materials": ["floor"]}],
        "world": {"type": "environment", "file": str(STAGE / "studio.exr"), "strength": 1.0},
    }


def render_thumbnail(info: PresetInfo, size: int = SIZE, spp: int = SPP, workers: int | None = None,
                     seed: int = SEED):
    """Render one preset on the stage; returns the RenderResult (film holds linear RGB)."""
    from .render import Renderer, RenderOptions
    from .scene.loader import load_scene_data
    data = stage_scene(absolute_textures(info.material, info.path.parent), size, spp, seed)
    where = f"{info.path} (thumbnail stage)"
    scene = load_scene_data(copy.deepcopy(data), where, STAGE)
    options = RenderOptions(workers=workers)
    options.apply(scene)
    return Renderer(scene, (data, where, str(STAGE)), options).run()


def smooth_preview(rgb: np.ndarray, var: np.ndarray, albedo: np.ndarray, normal: np.ndarray,
                   radius: int = 3) -> np.ndarray:
    """Edge-preserving smoothing of a noisy preview (cross-bilateral / one-pixel NL-means).

    Each pixel becomes a weighted mean of its (2·radius+1)² neighbours. Weights: a spatial
    Gaussian (σ 2 px); similarity of the normal pass (σ 0.2) and of the albedo pass (σ 0.1),
    which keep silhouettes and texture edges; and the colour distance of the two pixel means
    measured in units of their variances (Rousselle et al. 2012's NL-means distance, with
    one-pixel patches), which keeps detail that is not noise. All in linear RGB.
    """
    h, w, _ = rgb.shape
    r = int(radius)
    pad = lambda a: np.pad(np.asarray(a, dtype=np.float64), ((r, r), (r, r), (0, 0)), mode="edge")
    c_p, v_p, a_p, n_p = pad(rgb), pad(var), pad(albedo), pad(normal)
    rgb, var, albedo, normal = (np.asarray(x, dtype=np.float64) for x in (rgb, var, albedo, normal))
    acc = np.zeros_like(rgb)
    wsum = np.zeros((h, w))
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            win = (slice(r + dy, r + dy + h), slice(r + dx, r + dx + w))
            c2, v2 = c_p[win], v_p[win]
            wt = np.exp(-(dx * dx + dy * dy) / (2 * 2.0 ** 2))
            wt = wt * np.exp(-((normal - n_p[win]) ** 2).sum(-1) / (2 * 0.2 ** 2))
            wt = wt * np.exp(-((albedo - a_p[win]) ** 2).sum(-1) / (2 * 0.1 ** 2))
            # (Δ² − (var_p + min(var_p, var_q))) / (ε + var_p + var_q), ε keeps 0/0 away.
            d2 = (((rgb - c2) ** 2 - (var + np.minimum(var, v2))) / (1e-4 + var + v2)).mean(-1)
            wt = wt * np.exp(-np.maximum(d2, 0.0))
            acc += wt[..., None] * c2
            wsum += wt
    return acc / np.maximum(wsum, 1e-300)[..., None]   # the centre weight is 1: wsum ≥ 1


def write_thumbnail(info: PresetInfo, out: Path | None = None, smooth: bool = True,
                    **kwargs) -> tuple[Path, float]:
    from .imageio import write_preview
    t0 = time.perf_counter()
    result = render_thumbnail(info, **kwargs)
    film = result.film
    rgb = film.combined()
    if not np.all(np.isfinite(rgb)):
        from .errors import LaminaError
        raise LaminaError(f"{info.path}: thumbnail render produced NaN/Inf pixels")
    if smooth:
        rgb = smooth_preview(rgb, film.variance_of_mean(), film.albedo_image(), film.normal_image())
    out = out or info.thumbnail
    out.parent.mkdir(parents=True, exist_ok=True)
    write_preview(out, rgb)
    return out, time.perf_counter() - t0


# --------------------------------------------------------------------------- gallery page

CATEGORY_ORDER = ("reference", "metal", "paint", "plastic", "ceramic", "wood", "stone", "glass", "fabric")


def gallery_markdown(presets: list[PresetInfo], page: Path = GALLERY) -> str:
    def rel(p: Path) -> str:
        import os
        return os.path.relpath(p, page.parent).replace(os.sep, "/")

    order = {c: i for i, c in enumerate(CATEGORY_ORDER)}
    cats = sorted({p.category for p in presets}, key=lambda c: (order.get(c, len(order)), c))
    lines = [
        "# Material presets",
        "",
        "<!-- Generated by `python -m backend presets thumbnails`; edit the preset files, not this page. -->",
        "",
        f"{len(presets)} presets ship in [`presets/`](../presets/) (file format: "
        "[presets/README.md](../presets/README.md)). Use one anywhere a material is accepted by its name: "
        "`\"materials\": {\"body\": \"car-paint-red\"}` in a scene file, or "
        "`python -m backend bsdf albedo car-paint-red --theta 45`. "
        "`python -m backend presets list` lists them, `presets show NAME` prints one.",
        "",
        f"Thumbnails: a unit sphere on a checker floor (squares of {CHECKER * 100:.0f} cm) in a studio "
        f"environment with a key and a rim soft box, {SIZE}×{SIZE} px, {SPP} samples per pixel, "
        "rendered by Lamina (`python -m backend presets thumbnails`; indirect light clamped at "
        f"{CLAMP:g} and the preview smoothed by an edge-preserving filter). Layer stacks read from the top "
        "(facing the viewer) down; α is the microfacet roughness, η the index below an interface, σt the "
        "extinction (optical depth per unit thickness).",
        "",
    ]
    for cat in cats:
        lines += [f"## {cat.capitalize()}", "", "| | preset |", "|---|---|"]
        for p in sorted((p for p in presets if p.category == cat), key=lambda p: p.name):
            img = f"<img src=\"{rel(p.thumbnail)}\" width=\"{SIZE}\" alt=\"{p.name}\">" \
                if p.thumbnail.is_file() else "(no thumbnail)"
            text = (f"**{p.label}** — `{p.name}`<br>{p.description}<br>"
                    f"<sub>stack: {describe_stack(p.material)}"
                    + (f"; source: {p.source}" if p.source else "") + "</sub>")
            lines.append(f"| {img} | {text.replace('|', '/')} |")
        lines.append("")
    return "\n".join(lines)
