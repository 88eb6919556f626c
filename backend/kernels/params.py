"""Texturable parameters as kernel data: a constant, or a texture id and a constant factor.

``ParamPacker`` collects the images a scene's parameters use into one ``TextureTable``
(kernels/textures.py) and turns each Param into ``(values, texture_id)``:
* a constant:   (value × factor, −1)
* an image:     (scale × factor, id)  — the kernel multiplies the texture lookup by ``values``
Scalar params give one value, RGB params three. Per lane the kernel reads
``lookup(tex, id, u, v) × values`` where id ≥ 0, else ``values`` (``param_rgb``/``param_scalar``).
"""
from __future__ import annotations

import numpy as np

from .jit import inlined
from .textures import TextureTable, build_table, lookup


class ParamPacker:
    def __init__(self):
        self._images: list = []
        self._ids: dict = {}

    def texture_id(self, texels: np.ndarray) -> int:
        key = id(texels)
        if key not in self._ids:
            self._ids[key] = len(self._images)
            self._images.append(np.ascontiguousarray(texels, np.float32))
        return self._ids[key]

    def pack(self, param, channels: int, factor=1.0) -> tuple[np.ndarray, int]:
        """(values (channels,), texture id or −1) of a Param: each Param kind packs itself
        (``kernel_pack``: textures.py, materials/emission.py), so this module knows none."""
        factor = np.asarray(factor, dtype=np.float64)
        if param is None:
            return np.zeros(channels), -1
        if hasattr(param, "kernel_pack"):
            return param.kernel_pack(self, channels, factor)
        # A plain number or RGB triple (materials built in code)
        values = np.broadcast_to(np.asarray(param, np.float64).reshape(-1) * factor, (channels,))
        return np.array(values, np.float64), -1

    def table(self) -> TextureTable:
        return build_table(self._images)


@inlined
def param_rgb(tx, values, tex_id, u, v):
    """RGB parameter at (u, v): ``values`` is a 3-tuple (constant or texture factor)."""
    if tex_id >= 0:
        t = lookup(tx, tex_id, u, v)
        return (t[0] * values[0], t[1] * values[1], t[2] * values[2])
    return (values[0], values[1], values[2])


@inlined
def param_scalar(tx, value, tex_id, u, v):
    if tex_id >= 0:
        return lookup(tx, tex_id, u, v)[0] * value
    return value
