"""A layer stack bound to n shading points: interface BSDFs, slab media, refractive indices.

Geometry (shared by the walk and the estimators): interface l (0 = top) lies at global depth
t = l; slab k (medium k) fills k < t < k + 1. Inside a slab the media module uses a normalised
depth 0 (top) … 1 (bottom), so a medium vertex at normalised depth s in slab k has t = k + s.
Directions are in the material's local frame (z up); travelling along d changes t by −d_z per
unit length.

Refractive indices: ``eta_top`` the index outside above (1, or the coating's for a nested stack),
``eta_slab[k]`` the index of slab k,
``eta_bottom`` the index outside below (meaningful only for transmissive stacks).

Slab kinds, decided at bind time from constants ("skip what is not needed"):
  EMPTY       zero optical depth everywhere: crossing it costs nothing;
  ABSORBING   constant albedo 0: no scattering vertex, crossing multiplies by the transmittance;
  SCATTERING  free-flight sampling with medium vertices.
"""
from __future__ import annotations

import numpy as np

from ..materials.base import BSDF, BSDFSample, lanes

EMPTY, ABSORBING, SCATTERING = 0, 1, 2
GRAZING = 1e-7  # |d_z| below this cannot cross a slab (Guo's double-precision epsilon)


class NullBSDF(BSDF):
    """Index-matched pass-through interface: a delta transmission with weight 1."""

    transmissive = True
    delta_only = True
    has_delta = True

    def __init__(self, n: int):
        self.n = n

    def eval(self, wi, wo, rng=None, mode=0):
        return np.zeros((wi.shape[0], 3))

    def pdf(self, wi, wo, rng=None, mode=0):
        return np.zeros(wi.shape[0])

    def sample(self, wi, rng, mode=0):
        m = wi.shape[0]
        ok = wi[:, 2] != 0
        return BSDFSample(-wi, np.where(ok[:, None], 1.0, np.zeros((m, 3))), np.zeros(m),
                          np.ones(m, dtype=bool))

    def albedo(self):
        return np.ones((1, 3))

    def take(self, idx):
        idx = np.asarray(idx)
        return NullBSDF(int(idx.sum()) if idx.dtype == bool else idx.size)


def slab_kind(medium) -> int:
    if medium.is_empty:
        return EMPTY
    alb = np.asarray(medium.albedo)
    if alb.shape[0] == 1 and not np.any(alb):
        return ABSORBING
    return SCATTERING


class BoundStack:
    """Interface kernels (kernels.py) and slab operators (slab.py) bound to n lanes.

    Vectors are (3, m) arrays (one row per component) throughout the layered package.
    """

    def __init__(self, n: int, kernels: list, slabs: list, eta_slab, eta_bottom: float,
                 kinds: list[int], bsdfs: list | None = None, eta_top: float = 1.0):
        self.n = n
        self.kernels = kernels
        self.slabs = slabs          # SlabOps, or None for an empty slab
        self.kinds = kinds
        self.bsdfs = bsdfs          # the bound interface BSDFs (kept for take/inspection)
        self.N = len(kernels)
        self.eta_top = float(eta_top)   # index above the stack (1; a coating's for a nested stack)
        self.eta_slab = np.asarray(eta_slab, dtype=np.float64).reshape(-1)
        self.eta_bottom = float(eta_bottom)
        self.transmissive = bool(kernels[-1].transmissive)

    @classmethod
    def build(cls, n: int, ifaces: list, media: list, eta_slab, eta_bottom: float,
              eta_top: float = 1.0, normals: list | None = None) -> "BoundStack":
        """``normals``: per interface None or (3, 1|n) unit shading normals (normal maps)."""
        from .kernels import FramedKernel, kernel_for
        from .slab import SlabOps
        kinds = [slab_kind(m) for m in media]
        slabs = [None if k == EMPTY else SlabOps(m) for k, m in zip(kinds, media)]
        kernels = [kernel_for(b) for b in ifaces]
        for i, nrm in enumerate(normals or []):
            if nrm is not None:
                kernels[i] = FramedKernel(kernels[i], nrm)
        return cls(n, kernels, slabs, eta_slab, eta_bottom, kinds, ifaces, eta_top)

    @property
    def constant(self) -> bool:
        """No per-lane parameter anywhere: every lane's stack is the same."""
        return (all(k.constant for k in self.kernels) and
                all(s is None or s.constant for s in self.slabs))

    def expand(self, idx) -> "BoundStack":
        """The stack for lanes ``idx``, which may repeat (a joint walk of several directions
        per shading point); free for a constant stack."""
        if self.constant:
            return BoundStack(len(idx), self.kernels, self.slabs, self.eta_slab, self.eta_bottom,
                              self.kinds, None, self.eta_top)
        return self.take(idx)

    def take(self, idx) -> "BoundStack":
        idx = np.asarray(idx)
        n = int(idx.sum()) if idx.dtype == bool else idx.size
        return BoundStack(n, [k.take(idx) for k in self.kernels],
                          [None if s is None else s.take(idx) for s in self.slabs],
                          self.eta_slab, self.eta_bottom, self.kinds, None, self.eta_top)

    def eta_corr(self, slab: np.ndarray, exit_top: np.ndarray) -> np.ndarray:
        """(η_exit-side / η_slab)²: converts subpaths sampled from the exit direction (importance
        transport) into the adjoint transport they stand for (see connect.py)."""
        eta_k = self.eta_slab[slab]
        out = np.where(exit_top, self.eta_top, self.eta_bottom)
        return (out / eta_k) ** 2

    # ------------------------------------------------------------------ slab transport
    def transmittance(self, k: int, lane_idx, d, t0, t1):
        """Transmittance in slab k from global depth t0 to t1 along d ((3, m) or (m,); 0 if d
        does not lead from t0 to t1)."""
        if self.kinds[k] == EMPTY:
            diff = t1 - t0
            ok = ((diff * -d[2] > 0) & (np.abs(d[2]) >= GRAZING)) | (diff == 0)
            return ok * 1.0
        return self.slabs[k].take(lane_idx).transmittance(d, t0 - k, t1 - k)

    def depth_density(self, k: int, lane_idx, d, t0, t1, to_medium, approx: bool) -> np.ndarray:
        """(m,) density of sampling depth t1 from t0 along d by a free flight in slab k: per unit
        depth if ``to_medium`` else the probability of reaching the interface. Slabs crossed
        without sampling (empty, absorbing, or all slabs in the approximate pdf) give 1."""
        if approx or self.kinds[k] != SCATTERING:
            return np.ones(d.shape[1])
        return self.slabs[k].take(lane_idx).depth_pdf(d, t0 - k, t1 - k, to_medium)

    def pass_probability(self, k: int, lane_idx, d, t0, t1) -> np.ndarray:
        """(m,) channel-averaged transmittance (the approximate pdf's attenuation of a slab)."""
        T = self.transmittance(k, lane_idx, d, t0, t1)
        return T.mean(axis=0) if T.ndim == 2 else T
