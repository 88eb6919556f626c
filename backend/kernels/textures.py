"""Image textures per lane: bilinear between texel centres, repeating in u and v.

All of a scene's images live in one ``TextureTable``: texels of every image concatenated in one
float32 array (row 0 = the top of the image, channels 1 or 3, already linear and sanitised by
``backend/textures.py``), with each image's offset, width, height and channel count. UV follows
Blender (u right, v up, (0, 0) = bottom-left). A one-channel image returns its value in all three
components. Texels stay float32 (what the files hold); interpolation is float64.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from .jit import inlined, kernel

TextureTable = namedtuple("TextureTable", ["texels", "offset", "width", "height", "channels"])


def empty_table() -> TextureTable:
    return TextureTable(np.zeros(1, np.float32), np.zeros(1, np.int64), np.ones(1, np.int32),
                        np.ones(1, np.int32), np.ones(1, np.int32))


def build_table(images: list) -> TextureTable:
    """``images``: (H, W, C) float32 arrays (C = 1 or 3), in texture-id order."""
    if not images:
        return empty_table()
    offsets, total = [], 0
    for img in images:
        offsets.append(total)
        total += img.size
    texels = np.concatenate([np.ascontiguousarray(img, np.float32).ravel() for img in images])
    return TextureTable(texels, np.array(offsets, np.int64),
                        np.array([img.shape[1] for img in images], np.int32),
                        np.array([img.shape[0] for img in images], np.int32),
                        np.array([img.shape[2] for img in images], np.int32))


@inlined
def _texel(tx, t, x, y):
    c = tx.channels[t]
    base = tx.offset[t] + (y * tx.width[t] + x) * c
    v0 = np.float64(tx.texels[base])
    if c == 1:
        return (v0, v0, v0)
    return (v0, np.float64(tx.texels[base + 1]), np.float64(tx.texels[base + 2]))


@inlined
def lookup(tx, t, u, v):
    """Bilinear, repeating lookup of texture ``t`` at (u, v); texel centres at (i + 0.5)/w."""
    w = tx.width[t]
    h = tx.height[t]
    x = u * w - 0.5
    y = (1.0 - v) * h - 0.5       # v is up in UV space, rows go down in the image
    fx0 = math.floor(x)
    fy0 = math.floor(y)
    fx = x - fx0
    fy = y - fy0
    if not (math.isfinite(fx0) and math.isfinite(fy0)):
        return (0.0, 0.0, 0.0)
    x0 = int(fx0) % w
    y0 = int(fy0) % h
    x1 = (x0 + 1) % w
    y1 = (y0 + 1) % h
    a = _texel(tx, t, x0, y0)
    b = _texel(tx, t, x1, y0)
    c = _texel(tx, t, x0, y1)
    d = _texel(tx, t, x1, y1)
    gx = 1.0 - fx
    gy = 1.0 - fy
    return ((a[0] * gx + b[0] * fx) * gy + (c[0] * gx + d[0] * fx) * fy,
            (a[1] * gx + b[1] * fx) * gy + (c[1] * gx + d[1] * fx) * fy,
            (a[2] * gx + b[2] * fx) * gy + (c[2] * gx + d[2] * fx) * fy)


@inlined
def lookup_gradient(tx, t, u, v):
    """(∂/∂u, ∂/∂v) of the first channel of ``lookup`` at (u, v): the slopes of the bilinear
    patch the point lies in (a bump map's height gradient, kernels/integrator.py)."""
    w = tx.width[t]
    h = tx.height[t]
    x = u * w - 0.5
    y = (1.0 - v) * h - 0.5
    fx0 = math.floor(x)
    fy0 = math.floor(y)
    if not (math.isfinite(fx0) and math.isfinite(fy0)):
        return (0.0, 0.0)
    fx = x - fx0
    fy = y - fy0
    x0 = int(fx0) % w
    y0 = int(fy0) % h
    x1 = (x0 + 1) % w
    y1 = (y0 + 1) % h
    c = tx.channels[t]
    base = tx.offset[t]
    a = np.float64(tx.texels[base + (y0 * w + x0) * c])
    b = np.float64(tx.texels[base + (y0 * w + x1) * c])
    cc = np.float64(tx.texels[base + (y1 * w + x0) * c])
    d = np.float64(tx.texels[base + (y1 * w + x1) * c])
    d_dx = (b - a) * (1.0 - fy) + (d - cc) * fy
    d_dy = (cc - a) * (1.0 - fx) + (d - b) * fx
    return (d_dx * w, -d_dy * h)            # x = u·w − ½, y = (1 − v)·h − ½


@kernel
def lookup_batch(tx, t, uv, out):
    """out[i] = lookup at uv[i] (out has 1 or 3 columns)."""
    for i in range(uv.shape[0]):
        r = lookup(tx, t, uv[i, 0], uv[i, 1])
        out[i, 0] = r[0]
        if out.shape[1] == 3:
            out[i, 1] = r[1]
            out[i, 2] = r[2]
