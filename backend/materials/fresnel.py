"""Fresnel reflectance on arrays (broadcasting), for NumPy callers: the BSDF inspector, tests and
the layered walks. The maths lives once, per lane, in ``backend/kernels/fresnel.py`` (its
docstring has the conventions: signed ``cos_i``, ``eta = n_below / n_above``, conductor index
relative to the medium the light arrives in); these are NumPy ufuncs over it.

* ``dielectric_polarized(cos_i, eta)`` → (Rs, Rp, cos_t, eta_ti)
* ``dielectric(cos_i, eta)`` → (F, cos_t, eta_ti), F = 1 under total internal reflection
* ``conductor_polarized(cos_i, eta, k)`` → (Rs, Rp);  ``conductor(cos_i, eta, k)`` → F
"""
from __future__ import annotations

from ..kernels.ufuncs import conductor, conductor_polarized, dielectric, dielectric_polarized

__all__ = ["conductor", "conductor_polarized", "dielectric", "dielectric_polarized"]
