"""The BSDF interface every material implements (one module per material, one interface).

A scene-level :class:`Material` is *bound* to a batch of shading points (``bind(ctx)``), which
evaluates its textures once and returns a lane-bound :class:`BSDF`. All BSDF queries are arrays:

* Directions are in the local shading frame (z = shading normal, x = UV tangent), float64,
  shape (n, 3), unit length. ``wi`` and ``wo`` both point *away* from the surface.
  ``wi`` is the direction the path arrived from (towards the camera); ``wo`` is the direction
  being evaluated/sampled (towards the light) — Mitsuba's naming.
* ``eval(wi, wo, rng)`` returns f(wi, wo)·|cos θo| per RGB channel, shape (n, 3), for the
  non-delta part of the BSDF only.
* ``pdf(wi, wo, rng)`` returns the solid-angle density, shape (n,), with which ``sample`` picks wo
  (non-delta part). Stochastic BSDFs (layered) return an estimate, used only for MIS weights.
* ``sample(wi, rng)`` returns a :class:`BSDFSample`. Its ``weight`` is f·|cos θo|/p (delta lobes
  included) and is *never* recomputed as eval/pdf by callers: for stochastic BSDFs the three
  quantities are independent estimates.
* ``mode`` is the transport mode: RADIANCE (camera paths) scales refraction by 1/η², IMPORTANCE
  does not. Only transmissive BSDFs look at it.
* Random numbers come from ``rng`` (a numpy Generator); analytic BSDFs ignore it in eval/pdf.

Precision: BSDF maths runs in float64 — microfacet terms at α = 1e-4 and cosines down to 1e-6
lose all precision in float32 (1 − cos² cancels), and layered walks multiply many factors.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np

RADIANCE = 0
IMPORTANCE = 1


class BSDFSample(NamedTuple):
    wo: np.ndarray       # (n, 3) sampled direction, local frame, unit
    weight: np.ndarray   # (n, 3) f·|cos θo| / p; zero where sampling failed (path ends)
    pdf: np.ndarray      # (n,) solid-angle pdf for MIS; 0 where delta (not used there)
    delta: np.ndarray    # (n,) bool: a delta lobe was sampled (no MIS with light sampling)


@dataclass
class ShadingContext:
    """What a material needs to bind its parameters at n shading points."""

    uv: np.ndarray  # (n, 2) float64 texture coordinates (Blender's UV convention, v up)

    @property
    def n(self) -> int:
        return self.uv.shape[0]


def rows3(value) -> np.ndarray:
    """A bound RGB parameter or (n, 3) direction array as a C-contiguous float64 (m, 3) array
    (m = 1 for constants), the layout the compiled batch kernels take."""
    return np.ascontiguousarray(np.asarray(value, dtype=np.float64).reshape(-1, 3))


def rows1(value, dtype=np.float64) -> np.ndarray:
    """A bound scalar parameter (shape () or (n,)) as a contiguous (1,) or (n,) array."""
    return np.ascontiguousarray(np.asarray(value, dtype=dtype).reshape(-1))


def sample_arrays(n: int):
    """Output arrays (wo, weight, pdf, delta) of a batch ``sample`` kernel."""
    return np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n, dtype=bool)


def taken(idx) -> int:
    """How many lanes ``take(idx)`` keeps (a boolean mask or an index array)."""
    idx = np.asarray(idx)
    return int(idx.sum()) if idx.dtype == bool else idx.size


def lanes(value: np.ndarray, idx) -> np.ndarray:
    """Subset a bound parameter: constants (ndim 0, or leading dimension 1) stay as they are."""
    value = np.asarray(value)
    if value.ndim == 0 or value.shape[0] == 1:
        return value
    return value[idx]


class BSDF:
    """A material bound to n shading points. Subclasses implement the four queries and take()."""

    #: True if every lobe is a delta (no eval/pdf needed; NEE skipped for these lanes).
    delta_only: ClassVar[bool] = False
    #: True if some lobe is a delta (sample may return delta=True).
    has_delta: ClassVar[bool] = False
    #: True if it can transmit (wo on the other side of the surface from wi).
    transmissive: ClassVar[bool] = False
    #: True if eval/pdf/sample are stochastic estimates (layered).
    stochastic: ClassVar[bool] = False

    n: int

    def eval(self, wi: np.ndarray, wo: np.ndarray, rng: np.random.Generator,
             mode: int = RADIANCE) -> np.ndarray:
        raise NotImplementedError

    def pdf(self, wi: np.ndarray, wo: np.ndarray, rng: np.random.Generator,
            mode: int = RADIANCE) -> np.ndarray:
        raise NotImplementedError

    def sample(self, wi: np.ndarray, rng: np.random.Generator,
               mode: int = RADIANCE) -> BSDFSample:
        raise NotImplementedError

    def nee_and_sample(self, wi: np.ndarray, wo: np.ndarray, nee: np.ndarray,
                       rng: np.random.Generator, nee_pdf: bool = True, want_sample: bool = True):
        """One scattering event of a path (RADIANCE transport): ``eval(wi, wo)`` on the lanes
        where ``nee`` (bool (n,)) is set and 0 elsewhere; ``pdf(wi, wo)`` on those lanes if
        ``nee_pdf`` (else zeros), for the light sample's MIS weight; and, if ``want_sample``,
        ``sample(wi)`` for every lane. Returns (f (n, 3), pdf (n,), BSDFSample or None).

        Stochastic BSDFs override this to share random walks between the light connection and
        the continuation sample; the two stay unbiased estimates each (they may be correlated).
        """
        n = wi.shape[0]
        f = np.zeros((n, 3))
        pdf = np.zeros(n)
        k = np.flatnonzero(nee)
        if k.size == n:
            f = self.eval(wi, wo, rng)
            if nee_pdf:
                pdf = self.pdf(wi, wo, rng)
        elif k.size:
            # Only the lanes asked for: the others (occluded side, outside a light's cone, zero
            # value) would cost a full (possibly stochastic) evaluation for nothing.
            sub = self.take(k)
            wi_k, wo_k = np.take(wi, k, axis=0), np.take(wo, k, axis=0)
            f[k] = sub.eval(wi_k, wo_k, rng)
            if nee_pdf:
                pdf[k] = sub.pdf(wi_k, wo_k, rng)
        return f, pdf, (self.sample(wi, rng) if want_sample else None)

    def albedo(self) -> np.ndarray:
        """(n, 3) or (1, 3): an RGB estimate of the reflectance, for the albedo AOV (denoising)."""
        raise NotImplementedError

    def take(self, idx) -> "BSDF":
        """The same BSDF restricted to lanes ``idx`` (an index array or a boolean mask)."""
        raise NotImplementedError


class ClosedFormBSDF(BSDF):
    """A BSDF whose value and pdf come from one compiled call, ``_eval_pdf(wi, wo, mode)`` →
    (f (n, 3), pdf (n,)): ``eval`` and ``pdf`` are its two halves; and whose sampler is one
    compiled call too, ``_sample_into(wi, rng, mode, out)`` filling ``sample_arrays``."""

    def _eval_pdf(self, wi, wo, mode):
        raise NotImplementedError

    def _sample_into(self, wi, rng, mode, out) -> None:
        raise NotImplementedError

    def sample(self, wi, rng, mode=RADIANCE, **_):
        wi = rows3(wi)
        out = sample_arrays(wi.shape[0])
        self._sample_into(wi, rng, mode, out)
        return BSDFSample(*out)

    def eval(self, wi, wo, rng=None, mode=RADIANCE, **_):
        return self._eval_pdf(wi, wo, mode)[0]

    def pdf(self, wi, wo, rng=None, mode=RADIANCE, **_):
        return self._eval_pdf(wi, wo, mode)[1]


class NothingButDeltaBSDF(BSDF):
    """A BSDF without parameters and without a lobe to evaluate (a pass-through interface, a black
    surface): eval and pdf are 0, ``sample`` says what it does; its lanes are only a count."""

    delta_only = True

    def __init__(self, n: int):
        self.n = n

    def eval(self, wi, wo, rng=None, mode=0):
        return np.zeros((wi.shape[0], 3))

    def pdf(self, wi, wo, rng=None, mode=0):
        return np.zeros(wi.shape[0])

    def take(self, idx):
        return type(self)(taken(idx))


class Material:
    """A scene material. Parsed from the scene file, bound per shading batch.

    ``two_sided``: reflection-only materials are seen from both sides (the integrator flips the
    frame towards the arriving direction); transmissive ones are not flipped (the side matters).
    ``emission``: an RGB radiance Param (W m⁻² sr⁻¹) or None. ``emission_front_only``: it is
    emitted from the front side only (the scene file's ``"emission_sides": "front"``), else from
    both sides (as Cycles).
    """

    type_name: ClassVar[str] = ""
    two_sided: bool = True
    emission = None
    emission_front_only: bool = False

    def bind(self, ctx: ShadingContext) -> BSDF:
        raise NotImplementedError

    def pack(self, row) -> None:
        """Write this material's kind and parameters into its row of the compiled material
        table (``backend/kernels/materials.py``: ``MaterialRow``); emission is written by the
        table builder."""
        raise NotImplementedError

    #: The attributes holding this material's texturable parameters (``backend.textures.Param``).
    textured_params: ClassVar[tuple[str, ...]] = ()

    @property
    def uses_textures(self) -> bool:
        return any(p is not None and not p.is_constant
                   for p in (getattr(self, name) for name in self.textured_params))


def zeros3(n: int) -> np.ndarray:
    return np.zeros((n, 3))
