"""Anisotropic microfacet distributions (GGX, Beckmann) on arrays, for NumPy callers.

The maths — NDF, exact Smith Λ, the two masking forms, the NDF and visible-normal samplers and
their densities — lives once, per lane, in ``backend/kernels/microfacet.py`` (its docstring has
the conventions and references); this class binds α to lanes and loops the compiled functions
over (n, 3) arrays. α is clamped to ``ALPHA_MIN`` = 1e-4. Parameters: shape () or (n,).
"""
from __future__ import annotations

import numpy as np

from ..kernels.lazy import lazy
from ..kernels.microfacet_codes import ALPHA_MIN, DISTRIBUTION_CODES, MASKING_CODES

_b = lazy("microfacet_batch")     # compiled on first use (kernels/lazy.py)

GGX = "ggx"
BECKMANN = "beckmann"
HEIGHT_CORRELATED = "height-correlated"
SEPARABLE = "separable"
DISTRIBUTIONS = (GGX, BECKMANN)
MASKINGS = (HEIGHT_CORRELATED, SEPARABLE)

__all__ = ["ALPHA_MIN", "BECKMANN", "DISTRIBUTIONS", "GGX", "HEIGHT_CORRELATED", "MASKINGS",
           "Microfacet", "SEPARABLE"]


def _rows(v) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(v, dtype=np.float64).reshape(-1, 3))


class Microfacet:
    """A microfacet distribution bound to lanes (αu, αv of shape () or (n,))."""

    def __init__(self, distribution: str, alpha_u, alpha_v=None, masking: str = HEIGHT_CORRELATED):
        if distribution not in DISTRIBUTIONS:
            raise ValueError(f"unknown microfacet distribution {distribution!r}")
        if masking not in MASKINGS:
            raise ValueError(f"unknown masking {masking!r}")
        self.distribution = distribution
        self.masking = masking
        self.dist_code = DISTRIBUTION_CODES[distribution]
        self.masking_code = MASKING_CODES[masking]
        au = np.asarray(alpha_u, dtype=np.float64)
        av = au if alpha_v is None else np.asarray(alpha_v, dtype=np.float64)
        self.au = np.maximum(au, ALPHA_MIN)
        self.av = np.maximum(av, ALPHA_MIN)
        self._au = np.ascontiguousarray(self.au.reshape(-1))
        self._av = np.ascontiguousarray(self.av.reshape(-1))

    def _out(self, v):
        return np.empty(np.asarray(v).shape[0])

    def _query(self, batch, *directions, lead=()):
        """``batch(*lead, dist, αu, αv, *directions, out)`` over rows of unit vectors broadcast
        together."""
        rows = [np.ascontiguousarray(x) for x in np.broadcast_arrays(*map(_rows, directions))]
        out = self._out(rows[0])
        batch(*lead, self.dist_code, self._au, self._av, *rows, out)
        return out

    def D(self, m):
        return self._query(_b.of_direction, m, lead=(_b.D_OF,))

    def smith_lambda(self, w):
        return self._query(_b.of_direction, w, lead=(_b.LAMBDA_OF,))

    def G1(self, w, m):
        return self._query(_b.G1, w, m)

    def _G1_separable(self, w, m):
        """G1 of the separable form (Walter et al.'s rational fit for Beckmann)."""
        return self._query(_b.G1_separable, w, m)

    def G(self, wi, wo, m):
        wi, wo, m = (np.ascontiguousarray(x) for x in np.broadcast_arrays(_rows(wi), _rows(wo), _rows(m)))
        out = self._out(wi)
        _b.G(self.dist_code, self.masking_code, self._au, self._av, wi, wo, m, out)
        return out

    def sample_ndf(self, u):
        u = np.ascontiguousarray(u, dtype=np.float64)
        out = np.empty((u.shape[0], 3))
        _b.sample_ndf(self.dist_code, self._au, self._av, u, out)
        return out

    def pdf_ndf(self, m):
        return self._query(_b.of_direction, m, lead=(_b.PDF_NDF_OF,))

    def sample_visible(self, wi, u):
        """m ∝ G1(wi, m) max(0, wi·m) D(m)/wi.z for wi in the upper hemisphere (wi.z ≥ 0)."""
        u = np.ascontiguousarray(u, dtype=np.float64)
        wi = np.ascontiguousarray(np.broadcast_to(_rows(wi), (u.shape[0], 3)))
        out = np.empty((u.shape[0], 3))
        _b.sample_visible(self.dist_code, self._au, self._av, wi, u, out)
        return out

    def pdf_visible(self, wi, m):
        return self._query(_b.pdf_visible, wi, m)
