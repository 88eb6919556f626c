"""The ``null`` interface of layered stacks (an index-matched pass-through): its material and its
standalone BSDF.

The stacks themselves are kernel data: backend/kernels/layered/table.py (geometry, refractive
indices, slab kinds) and the per-lane walk and estimators next to it; stack_table.py builds it.
"""
from __future__ import annotations

import numpy as np

from ..materials.base import BSDFSample, Material, NothingButDeltaBSDF, ShadingContext


class NullBSDF(NothingButDeltaBSDF):
    """Index-matched pass-through interface: a delta transmission with weight 1."""

    transmissive = True
    has_delta = True

    def sample(self, wi, rng, mode=0):
        m = wi.shape[0]
        ok = wi[:, 2] != 0
        return BSDFSample(-wi, np.where(ok[:, None], 1.0, np.zeros((m, 3))), np.zeros(m),
                          np.ones(m, dtype=bool))

    def albedo(self):
        return np.ones((1, 3))


class NullMaterial(Material):
    type_name = "null"
    two_sided = False

    def bind(self, ctx: ShadingContext):
        return NullBSDF(ctx.n)
