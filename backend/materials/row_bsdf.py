"""A material evaluated through its row of the compiled material table, for NumPy callers (the
BSDF inspector, tests): the same per-lane code the integrator runs (kernels/materials.py
``bind`` / ``eval_pdf`` / ``sample`` / ``albedo``), over arrays of lanes. Used by the layered
stacks that have a deterministic form (backend/layered/coated_diffuse.py)."""
from __future__ import annotations

import numpy as np

from ..kernels.lazy import lazy
from .base import ClosedFormBSDF, rows3, taken

_batch = lazy("bsdf.batch")     # compiled on first use (kernels/lazy.py)


class RowBSDF(ClosedFormBSDF):
    """``material`` (one with a ``pack``) bound at ``uv`` ((1 | n, 2)) for n lanes. Reflection only
    and two-sided, like the stacks that use it; exact (not estimated) eval, pdf and weights."""

    has_delta = True

    def __init__(self, material, uv: np.ndarray, n: int):
        self.material = material
        self.uv = np.ascontiguousarray(np.asarray(uv, dtype=np.float64).reshape(-1, 2))
        self.n = int(n)

    def _table(self):
        table = getattr(self.material, "_row_table", None)
        if table is None:
            from ..kernels.materials import build_material_table
            from ..kernels.params import ParamPacker
            packer = ParamPacker()
            mt = build_material_table([self.material], packer)
            table = (mt, packer.table())
            self.material._row_table = table
        return table

    def _uv_for(self, n: int) -> np.ndarray:
        if self.uv.shape[0] in (1, n):
            return self.uv
        return np.ascontiguousarray(np.broadcast_to(self.uv[:1], (n, 2)))

    def _eval_pdf(self, wi, wo, mode):
        mt, tx = self._table()
        wi, wo = rows3(wi), rows3(wo)
        n = wi.shape[0]
        if wo.shape[0] != n:
            wo = np.ascontiguousarray(np.broadcast_to(wo, (n, 3)))
        f, pdf = np.empty((n, 3)), np.empty(n)
        _batch.row_eval_pdf(mt, tx, 0, self._uv_for(n), int(mode), wi, wo, f, pdf)
        return f, pdf



    def _sample_into(self, wi, rng, mode, out):
        mt, tx = self._table()
        n = wi.shape[0]
        _batch.row_sample(mt, tx, 0, self._uv_for(n), int(mode), wi, rng.random((n, 3)), *out)

    def albedo(self, wi=None):
        """The directional albedo per lane at ``wi`` (default: normal incidence)."""
        mt, tx = self._table()
        if wi is None:
            wi = np.zeros((self.n, 3))
            wi[:, 2] = 1.0
        wi = rows3(wi)
        out = np.empty((wi.shape[0], 3))
        _batch.row_albedo(mt, tx, 0, self._uv_for(wi.shape[0]), wi, out)
        return out

    def take(self, idx):
        idx = np.asarray(idx)
        n = taken(idx)
        return RowBSDF(self.material, self.uv if self.uv.shape[0] == 1 else self.uv[idx], n)
