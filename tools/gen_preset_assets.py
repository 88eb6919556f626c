#!/usr/bin/env python3
"""Generate the small procedural images used by the preset library and its thumbnail stage.

    python tools/gen_preset_assets.py          # (re)writes the files below; deterministic

presets/stage/checker.png        floor of the thumbnail stage: one 2 × 2 tile of a grey checker (sRGB
                                 8-bit); the floor mesh repeats it with its UVs
presets/stage/studio.exr         equirectangular studio environment (half float, linear Rec.709):
                                 a soft sky gradient, a dim floor and two soft boxes (key + rim)
presets/textures/wood_grain.png  lacquer thickness multiplier of `lacquered-wood`: growth rings
                                 with a wavy distortion and fine pores, grey, linear in [0.25, 1]
presets/textures/twill_weave.png fiber orientation of `gabardine`: a 2/2 twill (64 threads) of warp (tangent x)
                                 and weft (bitangent y) threads, encoded like a normal map
presets/textures/enamel_pattern.png  enamel thickness multiplier of `enamelled-silver`: 4 × 2
                                 rosettes of rings and petals, grey, linear in [0, 1]

Everything is plain NumPy (no noise library) so the output is bit-identical on every machine.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PRESETS = ROOT / "presets"


def write_image(path: Path, pixels: np.ndarray, half: bool = False) -> None:
    import OpenImageIO as oiio
    path.parent.mkdir(parents=True, exist_ok=True)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]          # OIIO wants (height, width, channels)
    pixels = np.ascontiguousarray(pixels)
    h, w, c = pixels.shape
    if path.suffix == ".exr":
        spec = oiio.ImageSpec(w, h, c, "half" if half else "float")
        spec.attribute("compression", "zip")
        spec.attribute("DateTime", "2000:01:01 00:00:00")   # fixed: deterministic output
        data = pixels.astype(np.float32)
    else:
        spec = oiio.ImageSpec(w, h, c, "uint8")
        data = np.clip(np.round(pixels * 255.0), 0, 255).astype(np.uint8)
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec):
        raise SystemExit(f"cannot write {path}: {oiio.geterror()}")
    out.write_image(data)
    out.close()
    print(f"wrote {path.relative_to(ROOT)} ({w}×{h}×{c})")


def smooth_noise(shape: tuple[int, int], periods: int, seed: int) -> np.ndarray:
    """Tileable value noise in [0, 1]: a sum of random-phase sines on integer frequencies."""
    rng = np.random.default_rng(seed)
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    u, v = x / w, y / h
    out = np.zeros(shape)
    for _ in range(12):
        fx, fy = rng.integers(-periods, periods + 1, size=2)
        amp = 1.0 / (1.0 + np.hypot(fx, fy))
        out += amp * np.sin(2 * np.pi * (fx * u + fy * v) + rng.uniform(0, 2 * np.pi))
    out -= out.min()
    return out / max(out.max(), 1e-12)


def checker(size: int = 32, squares: int = 2) -> np.ndarray:
    y, x = np.mgrid[0:size, 0:size]
    cell = size // squares
    odd = ((x // cell) + (y // cell)) % 2
    srgb = np.where(odd, 0.78, 0.30)       # sRGB-encoded greys → linear ≈ 0.57 and 0.07
    return np.repeat(srgb[:, :, None], 3, axis=2)


def studio(width: int = 256, height: int = 128) -> np.ndarray:
    """Equirectangular map in Blender's orientation (backend/lights/environment.py).

    Column u ↔ azimuth φ = π(1 − 2u) (centre = +X), row v (0 = top) ↔ polar θ = π(v + ½)/H.
    The thumbnail camera looks along +Y from −Y; the key box sits front-left above the camera,
    the rim box behind-right of the sphere.
    """
    v, u = (np.mgrid[0:height, 0:width] + 0.5)
    u, v = u / width, v / height
    phi = np.pi * (1.0 - 2.0 * u)
    theta = np.pi * v
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)
    up = np.clip(d[..., 2], 0, 1)
    sky = (1 - up)[..., None] * np.array([0.55, 0.58, 0.62]) + up[..., None] * np.array([0.22, 0.3, 0.45])
    ground = np.array([0.12, 0.11, 0.10])
    img = np.where(d[..., 2:3] >= 0, sky, ground)

    def softbox(direction, radius_deg, radiance):
        c = np.asarray(direction, float)
        c /= np.linalg.norm(c)
        ang = np.degrees(np.arccos(np.clip(d @ c, -1, 1)))
        # Flat-topped disc with a soft 4° edge (smoothstep), so highlights have a clean shape.
        t = np.clip((radius_deg + 2 - ang) / 4.0, 0, 1)
        return (t * t * (3 - 2 * t))[..., None] * np.asarray(radiance)

    img = img + softbox([-0.55, -0.7, 0.75], 24, [3.2, 3.05, 2.85])   # key: front-left, high
    img = img + softbox([0.8, 0.7, 0.35], 14, [1.2, 1.3, 1.6])        # rim: behind-right, cool
    return img


def wood_grain(size: int = 256) -> np.ndarray:
    y, x = np.mgrid[0:size, 0:size] / size
    warp = smooth_noise((size, size), 3, 1)
    # Rings run along u (the grain follows the tangent), distorted by low-frequency noise;
    # 9 rings per tile so the pattern tiles (integer frequency); the distortion is < 1 ring.
    phase = 9 * y + 0.6 * np.sin(2 * np.pi * x) + 0.5 * warp
    ring = 0.5 + 0.5 * np.cos(2 * np.pi * phase)
    late = ring ** 6                                   # narrow dark latewood bands
    pores = smooth_noise((size, size), 40, 2)
    value = 0.35 + 0.5 * late + 0.15 * pores
    return np.clip(value, 0.25, 1.0)


def twill(size: int = 256, threads: int = 64) -> np.ndarray:
    """2/2 twill: the warp floats over two wefts, shifted by one thread per row."""
    y, x = np.mgrid[0:size, 0:size]
    cell = size // threads
    i, j = x // cell, y // cell
    warp_on_top = ((i + j) % 4) < 2
    warp = np.array([1.0, 0.0, 0.0])                   # fiber along the UV tangent
    weft = np.array([0.0, 1.0, 0.0])                   # fiber along the bitangent
    vec = np.where(warp_on_top[..., None], warp, weft)
    return 0.5 * vec + 0.5                             # normal-map encoding: value·2 − 1


def enamel(width: int = 512, height: int = 256) -> np.ndarray:
    """4 × 2 rosettes (8 petals in a ring): round on a UV sphere, whose u spans twice its v."""
    y, x = (np.mgrid[0:height, 0:width] + 0.5)
    cx, cy = (x * 4 / width) % 1 - 0.5, (y * 2 / height) % 1 - 0.5
    r = np.hypot(cx, cy)
    a = np.arctan2(cy, cx)
    petal = np.clip(1 - np.abs(r - (0.22 + 0.08 * np.cos(8 * a))) / 0.05, 0, 1)
    ring = np.clip(1 - np.abs(r - 0.42) / 0.025, 0, 1)
    dot = np.clip(1 - r / 0.07, 0, 1)
    value = np.maximum.reduce([petal, ring, dot])
    return value * value * (3 - 2 * value)


def main() -> int:
    write_image(PRESETS / "stage" / "checker.png", checker())
    write_image(PRESETS / "stage" / "studio.exr", studio(), half=True)
    write_image(PRESETS / "textures" / "wood_grain.png", wood_grain())
    write_image(PRESETS / "textures" / "twill_weave.png", twill())
    write_image(PRESETS / "textures" / "enamel_pattern.png", enamel())
    return 0


if __name__ == "__main__":
    sys.exit(main())
