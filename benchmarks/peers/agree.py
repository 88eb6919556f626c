"""Do Lamina and Cycles render the same image? A region-by-region check of two converged renders.

**Regions** come from the scene description, not from either image: camera rays through a 5 × 5
grid of points spanning each pixel's filter support (±width/2 of Lamina's ``film.filter``) are traced
against the scene's triangles (the loader's, with embree) and against the area lights visible to
the camera. A pixel whose points all see the same object (or the same light, or all escape to
the world) belongs to that object's region; pixels that straddle an outline form the "edges"
region. Large regions are cut by a coarse image grid so that a local difference (a light turned
the wrong way, a misplaced highlight) is not averaged away over a whole wall.

**Test.** Per region and RGB channel, the mean of each image and its standard error
σ = √(Σ var_of_mean) / n (pixels independent). Lamina's per-pixel variance of the mean comes from
its film; Cycles', from ``REF_SPLIT`` independent renders (sample variance across them / count).
A region fails when |m_L − m_C| > k · √(σ_L² + σ_C²) + tol · |m_C|: k = ``K_SIGMA`` (with about a
hundred tests, k = 4 keeps the chance of a false alarm near 1 % for Gaussian errors), tol =
``REL_TOL`` for differences that remain however long both renderers sample (0 unless the report
names a cause).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

K_SIGMA = 4.0
REL_TOL = 0.0
SUB = 5                 # sub-pixel rays per axis for the labels
GRID = 3                # image cut into GRID × GRID tiles for big regions
MIN_PIXELS = 24         # smallest region tested on its own


# --------------------------------------------------------------------------- labels

def _camera_rays(camera: dict, width: int, height: int, half_width: float):
    """World-space rays through a SUB × SUB grid spanning ±half_width pixels around each pixel
    centre (pixel (0, 0) at the top left, as both renderers store it). Shape (H, W, SUB², 3)."""
    frame = np.asarray(camera["frame"], dtype=np.float64)
    tr, _, bl, tl = frame
    m = np.asarray(camera["to_world"], dtype=np.float64)
    off = np.linspace(-half_width, half_width, SUB)
    ox, oy = np.meshgrid(off, off)
    ys, xs = np.mgrid[0:height, 0:width]
    s = (xs[..., None] + 0.5 + ox.ravel()) / width
    t = (ys[..., None] + 0.5 + oy.ravel()) / height
    d_cam = tl + s[..., None] * (tr - tl) + t[..., None] * (bl - tl)
    d = d_cam @ m[:3, :3].T
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return np.broadcast_to(m[:3, 3], d.shape).copy(), d


def _hit_area_light(light: dict, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Distance to a visible area light along each ray (inf where missed or seen from behind)."""
    m = np.asarray(light["to_world"], dtype=np.float64)
    inv = np.linalg.inv(m)
    ol = o @ inv[:3, :3].T + inv[:3, 3]
    dl = d @ inv[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -ol[:, 2] / dl[:, 2]                     # rays parallel to the light: inf/nan, never inside
        p = ol + t[:, None] * dl
    sx = float(light.get("size", 1.0))
    sy = float(light.get("size_y", sx)) if light.get("shape", "square") in ("rectangle", "ellipse") else sx
    if light.get("shape", "square") in ("disk", "ellipse"):
        inside = (p[:, 0] / (sx / 2)) ** 2 + (p[:, 1] / (sy / 2)) ** 2 <= 1
    else:
        inside = (np.abs(p[:, 0]) <= sx / 2) & (np.abs(p[:, 1]) <= sy / 2)
    # Emission leaves along local −Z: the camera must be on that side (ray going towards +Z).
    front = dl[:, 2] > 0
    ok = inside & front & (t > 0)
    # The ray parameter is the same in both frames (an affine map keeps o + t·d's t), so t is the
    # world distance along the unit world ray.
    return np.where(ok, t, np.inf)


def filter_radius(data: dict) -> float:
    """Half the support of the scene's pixel filter (backend/film.py: SUPPORT × width)."""
    from backend.film import SUPPORT
    filt = data["film"].get("filter", {})
    kind = filt.get("type", "blackman-harris")
    return SUPPORT[kind] * float(filt.get("width", 1.0 if kind == "box" else 1.5)) / 2.0


def labels(data: dict, soup_vertices: np.ndarray, object_id: np.ndarray, half_width: float | None = None):
    """Per-pixel region names from the scene: (H, W) int array and the list of names.
    ``soup_vertices`` (T, 3, 3) and ``object_id`` (T,) are the loader's flattened triangles."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    W, H = int(data["film"]["width"]), int(data["film"]["height"])
    half_width = filter_radius(data) if half_width is None else half_width
    o, d = _camera_rays(data["camera"], W, H, half_width)
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(soup_vertices, dtype=np.float32))
    res = scene.run(o.astype(np.float32), d.astype(np.float32), output=True)
    prim = np.asarray(res["primID"]).astype(np.int64)
    tfar = np.where(prim >= 0, np.asarray(res["tfar"], dtype=np.float64), np.inf)
    objects = data.get("objects", [])
    names = [obj.get("name", f"object {i}") for i, obj in enumerate(objects)]
    lab = np.where(prim >= 0, object_id[np.maximum(prim, 0)], -1).astype(np.int64)
    world = len(names)
    names.append("world")
    lab[lab < 0] = world
    for li, light in enumerate(data.get("lights", [])):
        if light.get("type") == "area" and light.get("visible_camera", False):
            t = _hit_area_light(light, o, d)
            names.append(f"light {li} (seen directly)")
            lab[t < tfar] = len(names) - 1
    lab = lab.reshape(H, W, SUB * SUB)
    pure = np.all(lab == lab[..., :1], axis=-1)
    names.append("edges")
    out = np.where(pure, lab[..., 0], len(names) - 1)
    return out, names


def regions(label_img: np.ndarray, names: list[str], grid: int = GRID, min_pixels: int = MIN_PIXELS,
            whole: bool = True):
    """Cut each label into image tiles: list of (name, boolean mask). Tiles smaller than
    ``min_pixels`` are merged into one remainder per label; labels smaller than that are dropped
    (reported as such by the caller). With ``whole``, the whole image comes first as one more
    region: the most sensitive test of an overall brightness difference (in the noisiest scene,
    the IES room, a tile detects 1–11 %, the whole image 0.6 %)."""
    H, W = label_img.shape
    ty = np.minimum(np.arange(H) * grid // H, grid - 1)
    tx = np.minimum(np.arange(W) * grid // W, grid - 1)
    tile = ty[:, None] * grid + tx[None, :]
    out = [("whole image", np.ones_like(label_img, dtype=bool))] if whole else []
    for li, name in enumerate(names):
        mask = label_img == li
        n = int(mask.sum())
        if n < min_pixels:
            continue
        if n < 2 * min_pixels:
            out.append((name, mask))
            continue
        rest = np.zeros_like(mask)
        for k in range(grid * grid):
            m = mask & (tile == k)
            c = int(m.sum())
            if c >= min_pixels:
                out.append((f"{name} [{'tmb'[k // grid]}{'lcr'[k % grid]}]", m))
            elif c:
                rest |= m
        if rest.sum() >= min_pixels:
            out.append((f"{name} [rest]", rest))
        elif rest.any() and out and out[-1][0].startswith(name):
            # Too small alone: join the last tile of the same label.
            out[-1] = (out[-1][0], out[-1][1] | rest)
    return out


# --------------------------------------------------------------------------- the test

@dataclass
class RegionResult:
    name: str
    pixels: int
    mean_a: np.ndarray      # (3,) Lamina
    mean_b: np.ndarray      # (3,) Cycles
    se: np.ndarray          # (3,) standard error of the difference
    z: np.ndarray           # (3,) difference / se
    allowed: np.ndarray     # (3,) k·se + tol·|mean_b|
    ok: bool

    @property
    def rel_diff(self) -> np.ndarray:
        return (self.mean_a - self.mean_b) / np.where(self.mean_b != 0, np.abs(self.mean_b), 1.0)

    def summary(self) -> dict:
        return {"region": self.name, "pixels": self.pixels, "lamina": self.mean_a.tolist(), "cycles": self.mean_b.tolist(),
                "rel_diff": self.rel_diff.tolist(), "z": self.z.tolist(), "ok": self.ok}


def check(img_a: np.ndarray, var_a: np.ndarray, img_b: np.ndarray, var_b: np.ndarray, region_list: list,
          k: float = K_SIGMA, tol: float = REL_TOL) -> list[RegionResult]:
    """Compare region means of two images (H, W, 3) given per-pixel variances of the mean."""
    out = []
    for name, mask in region_list:
        n = int(mask.sum())
        ma = img_a[mask].mean(axis=0)
        mb = img_b[mask].mean(axis=0)
        se = np.sqrt(var_a[mask].sum(axis=0) + var_b[mask].sum(axis=0)) / n
        diff = ma - mb
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(se > 0, diff / se, np.where(diff == 0, 0.0, np.inf))
        allowed = k * se + tol * np.abs(mb)
        ok = bool(np.all(np.abs(diff) <= allowed))
        out.append(RegionResult(name, n, ma, mb, se, z, allowed, ok))
    return out


def split_variance(renders: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Mean of K independent renders and the per-pixel variance of that mean (sample variance
    across the renders / K)."""
    stack = np.stack(renders)
    k = stack.shape[0]
    if k < 2:
        raise ValueError("need at least two independent renders to estimate the variance")
    return stack.mean(axis=0), stack.var(axis=0, ddof=1) / k


def verdict(results: list[RegionResult]) -> dict:
    bad = [r for r in results if not r.ok]
    zmax = max((float(np.max(np.abs(r.z))) for r in results if np.all(np.isfinite(r.z))), default=math.nan)
    return {"regions": len(results), "failed": len(bad), "failed_names": [r.name for r in bad], "max_abs_z": zmax,
            "ok": not bad}
