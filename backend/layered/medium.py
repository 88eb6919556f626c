"""One slab of participating medium inside a layered stack: extinction, albedo, phase, free flights.

Conventions (shared with the layered walk)
------------------------------------------
* **Depth** is normalised per slab: 0 = the slab's top (the interface above it), 1 = its bottom.
  Geometric thickness enters only through the optical depth τ0 = sigma_t × thickness (docs/materials.md, Media).
* **Directions** are propagation directions in the layer frame, (n, 3) unit float64, z = stack
  normal pointing up. A direction with d_z < 0 goes *down*, i.e. towards larger depth.
* **Extinction along a direction**: optical thickness per unit normalised depth is
  ``density(d)`` = τ0 · phase.sigma_scale(d) (per RGB channel); travelling a depth interval Δ
  along d accumulates density(d) · Δ / |d_z| (the paper's distance t ↔ depth |d_z| t).
  ``sigma_scale`` is 1 except for microflake phases (direction-dependent σt).
* **Densities** for MIS are in the paper's position-free measure: a scattering depth has density
  per unit normalised depth (rate/|d_z| units), reaching the boundary has a probability.
* Grazing directions (|d_z| < GRAZING = 1e-7, Guo's double-precision epsilon) cannot cross the slab:
  ``free_flight`` returns weight 0 for them (the walk kills such lanes).

Parameter shapes follow ``materials.base.lanes``: constants (), (1, 3); per lane (n,), (n, 3).

Free-flight sampling with chromatic σt uses the "balance" strategy of Mitsuba (the chromatic extinction part of backend/kernels/layered/walk.py's docstring): pick an
RGB channel uniformly, sample an exponential depth with that channel's rate, and weight with the
channel-averaged densities — scatter: albedo_k σ_k e^{−σ_k Δ}/mean_j(σ_j e^{−σ_j Δ});
pass: e^{−σ_k Δmax}/mean_j e^{−σ_j Δmax} (rates per unit depth along d). For grey media the
weights are exactly the albedo and 1.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .phase import Isotropic, Phase, PhaseSpec, parse_phase
from .phase.parse import isotropic_spec
from .phase.base import lanes

GRAZING = 1e-7


class FreeFlight(NamedTuple):
    depth: np.ndarray      # (n,) new normalised depth (0 or 1 when the boundary was reached)
    scattered: np.ndarray  # (n,) bool: a medium vertex at ``depth``; False: reached the boundary (or dead)
    weight: np.ndarray     # (n, 3) throughput factor: albedo-type weight on scatter, T/p_pass on pass; 0 = dead
    pdf: np.ndarray        # (n,) scatter: density per unit normalised depth; pass: probability; 0 = dead


def _is_scalar(v) -> bool:
    """Grey input: a number, a () array or a 1-D array of per-lane values. RGB input: a Python
    list/tuple of 3 numbers, or a (1, 3) / (n, 3) array (a 1-D ndarray is never read as RGB,
    so three lanes of a grey texture cannot be mistaken for a colour)."""
    if isinstance(v, (list, tuple)):
        return False
    return np.ndim(v) <= 1


def _rgb_lanes(v) -> np.ndarray:
    """RGB as (1, 3) or (n, 3); grey input (see ``_is_scalar``) is repeated over the channels."""
    scalar = _is_scalar(v)
    v = np.asarray(v, dtype=np.float64)
    if scalar:
        return np.full((1, 3), float(v)) if v.size == 1 else np.repeat(v.reshape(-1, 1), 3, axis=1)
    return v.reshape(-1, 3)


def _scalar_lanes(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v.reshape(()) if v.size == 1 else v.reshape(-1)


class Medium:
    """A homogeneous slab bound to n lanes (or constant).

    ``thickness`` () or (n,); ``sigma_t`` extinction per unit thickness, grey (number, () or (n,))
    or RGB (list of 3, (1, 3) or (n, 3)); ``albedo`` likewise; ``phase`` a lane-bound Phase
    (default isotropic). ``grey`` (σt equal in all channels on every lane) is detected if omitted.
    """

    def __init__(self, thickness=1.0, sigma_t=1.0, albedo=1.0, phase: Phase | None = None,
                 grey: bool | None = None):
        scalar_sigma = _is_scalar(sigma_t)
        self.thickness = _scalar_lanes(thickness)
        self.sigma_t = _rgb_lanes(sigma_t)
        self.albedo = _rgb_lanes(albedo)
        self.phase = phase if phase is not None else Isotropic()
        if grey is None:
            grey = scalar_sigma or bool(np.all(self.sigma_t == self.sigma_t[:, :1]))
        self.grey = grey
        t = self.thickness
        self.optical_depth = self.sigma_t * (t[:, None] if t.ndim else t)  # τ0 per channel

    # ------------------------------------------------------------------ properties
    @property
    def is_empty(self) -> bool:
        """True if every lane has zero optical depth: the walk skips free-flight sampling."""
        return not np.any(self.optical_depth)

    @property
    def empty_lanes(self) -> np.ndarray:
        """(n,) or (1,) bool: lanes whose slab has zero optical depth in every channel."""
        return ~np.any(self.optical_depth > 0, axis=1)

    @property
    def directional(self) -> bool:
        return self.phase.directional

    # ------------------------------------------------------------------ extinction
    def density(self, d: np.ndarray) -> np.ndarray:
        """(n, 3): optical depth of the whole slab measured *along the normal* for light travelling
        along d, τ0 · sigma_scale(d). Divide by |d_z| for the rate along the ray per unit depth."""
        if not self.phase.directional:
            return np.broadcast_to(self.optical_depth, (d.shape[0], 3)).copy()
        return self.optical_depth * self.phase.sigma_scale(d)[:, None]

    def sigma_s(self, d: np.ndarray) -> np.ndarray:
        """(n, 3): scattering coefficient per unit normalised depth for light arriving along d
        (albedo · density(d)), the factor of the paper's reduced phase function σs·p."""
        return self.albedo * self.density(d)

    def _rate(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rate (n, 3) per unit depth along d, alive (n,) bool)."""
        az = np.abs(d[:, 2])
        alive = az >= GRAZING
        return self.density(d) / np.where(alive, az, 1.0)[:, None], alive

    def transmittance(self, d: np.ndarray, depth0=None, depth1=None) -> np.ndarray:
        """(n, 3) transmittance along d through the whole slab (depths omitted) or from depth0 to
        depth1. Includes the paper's indicator: 0 if moving along d does not lead from depth0 to
        depth1 (d_z < 0 goes to larger depth); 1 for a zero-length interval; 0 for grazing d."""
        rate, alive = self._rate(d)
        if depth0 is None:
            delta = np.ones(d.shape[0])
            reach = np.ones(d.shape[0], dtype=bool)
        else:
            diff = np.asarray(depth1, dtype=np.float64) - np.asarray(depth0, dtype=np.float64)
            diff = np.broadcast_to(diff, (d.shape[0],))
            delta = np.abs(diff)
            reach = (diff * -d[:, 2] > 0) | (diff == 0)
        t = np.exp(-rate * delta[:, None])
        t = np.where((reach & alive)[:, None], t, 0.0)
        if depth0 is not None:
            t = np.where((delta == 0)[:, None], 1.0, t)
        return t

    # ------------------------------------------------------------------ free flights
    def free_flight(self, depth: np.ndarray, d: np.ndarray, rng: np.random.Generator) -> FreeFlight:
        """Sample the next event along d from ``depth`` (normalised, (n,)): a scattering depth
        inside the slab or the boundary ahead (0 if d_z > 0, else 1)."""
        n = d.shape[0]
        depth = np.broadcast_to(np.asarray(depth, dtype=np.float64), (n,))
        rate, alive = self._rate(d)
        up = d[:, 2] > 0
        boundary = np.where(up, 0.0, 1.0)
        dmax = np.maximum(np.where(up, depth, 1.0 - depth), 0.0)  # depth left to the boundary
        u = rng.random((n, 2)) if not self.grey else rng.random((n, 1))
        if self.grey:
            r = rate[:, 0]
        else:
            ch = np.minimum((u[:, 1] * 3.0).astype(np.int64), 2)
            r = rate[np.arange(n), ch]
        with np.errstate(divide="ignore"):
            step = -np.log1p(-u[:, 0]) / r  # ∞ where this channel's rate is 0
        scattered = (step < dmax) & alive
        step = np.where(scattered, step, dmax)
        new_depth = np.where(scattered, np.where(up, depth - step, depth + step), boundary)
        new_depth = np.where(alive, new_depth, depth)
        if self.grey:
            e = np.exp(-r * step)
            pdf = np.where(scattered, r * e, e)
            weight = np.where(scattered[:, None], self.albedo, 1.0)
            weight = np.broadcast_to(weight, (n, 3))
        else:
            weight, pdf = self._balance(rate, step, scattered)
        weight = np.where(alive[:, None], weight, 0.0)
        pdf = np.where(alive, pdf, 0.0)
        return FreeFlight(new_depth, scattered, weight, pdf)

    def _balance(self, rate: np.ndarray, step: np.ndarray, scattered: np.ndarray):
        """Balance-heuristic weights and densities (see module docstring), computed in log space
        so that long steps do not underflow to 0/0."""
        with np.errstate(divide="ignore"):
            log_rate = np.where(scattered[:, None], np.log(rate), 0.0)
        log_term = log_rate - rate * step[:, None]  # −∞ for zero-rate channels when scattering
        top = np.max(log_term, axis=1)
        top = np.where(np.isfinite(top), top, 0.0)
        rel = np.exp(log_term - top[:, None])
        mean_rel = rel.mean(axis=1)
        ok = mean_rel > 0
        factor = np.where(scattered[:, None], self.albedo, 1.0)
        weight = factor * rel / np.where(ok, mean_rel, 1.0)[:, None]
        weight = np.where(ok[:, None], weight, 0.0)
        pdf = mean_rel * np.exp(top)
        return weight, pdf

    def free_flight_pdf(self, depth0, depth1, d: np.ndarray, scattered) -> np.ndarray:
        """(n,) density with which ``free_flight`` from depth0 along d produces depth1: per unit
        depth if ``scattered`` (depth1 is a medium vertex), else the probability of reaching the
        boundary depth1. For reverse-edge densities in MIS. Direction consistency is not checked."""
        n = d.shape[0]
        rate, alive = self._rate(d)
        delta = np.abs(np.broadcast_to(np.asarray(depth1, np.float64) - np.asarray(depth0, np.float64), (n,)))
        scattered = np.broadcast_to(np.asarray(scattered, dtype=bool), (n,))
        with np.errstate(divide="ignore"):
            e = np.exp(-rate * delta[:, None])
        terms = np.where(scattered[:, None], rate * e, e)
        return np.where(alive, terms.mean(axis=1), 0.0)

    # ------------------------------------------------------------------ lanes
    def take(self, idx) -> "Medium":
        other = Medium.__new__(Medium)
        other.thickness = lanes(self.thickness, idx)
        other.sigma_t = lanes(self.sigma_t, idx)
        other.albedo = lanes(self.albedo, idx)
        other.optical_depth = lanes(self.optical_depth, idx)
        other.phase = self.phase.take(idx)
        other.grey = self.grey
        return other

    def __repr__(self) -> str:
        return (f"Medium(optical_depth={self.optical_depth.shape}, grey={self.grey}, "
                f"phase={type(self.phase).__name__})")


# ---------------------------------------------------------------------------- scene schema
class MediumSpec:
    """A parsed ``media[i]`` entry (texturable Params); ``bind(uv)`` gives a :class:`Medium`."""

    def __init__(self, thickness, sigma_t, albedo, phase: PhaseSpec, grey: bool):
        self.thickness = thickness
        self.sigma_t = sigma_t
        self.albedo = albedo
        self.phase = phase
        self.grey = grey

    @property
    def is_empty(self) -> bool:
        """True when the slab is known at load time to have zero optical depth everywhere."""
        for p in (self.thickness, self.sigma_t):
            if p.is_constant and not np.any(p.bind(None)):
                return True
        return False

    @property
    def uses_textures(self) -> bool:
        return (not (self.thickness.is_constant and self.sigma_t.is_constant and self.albedo.is_constant)
                or self.phase.uses_textures)

    @property
    def directional(self) -> bool:
        return self.phase.directional

    def bind(self, uv: np.ndarray) -> Medium:
        return Medium(self.thickness.bind(uv), self.sigma_t.bind(uv), self.albedo.bind(uv),
                      self.phase.bind(uv), grey=self.grey)


def parse_medium(node) -> MediumSpec:
    """Parse one ``media[i]`` object (a ``scene.reader.Node``); errors name the field path."""
    node.require_object()
    thickness = node.param("thickness", 1.0, lo=0.0)
    raw = node.value.get("sigma_t", 1.0)
    if isinstance(raw, (int, float)) and not isinstance(raw, bool):
        sigma_t = node.param("sigma_t", 1.0, lo=0.0)
        grey = True
    else:
        sigma_t = node.param("sigma_t", channels=3, lo=0.0, color=False)
        grey = sigma_t.is_constant and bool(np.all(sigma_t.bind(None) == sigma_t.bind(None)[0, 0]))
    albedo = node.param("albedo", 1.0, channels=3, lo=0.0, hi=1.0)
    phase_node = node.optional_child("phase")
    phase = parse_phase(phase_node) if phase_node is not None else isotropic_spec()
    node.finish()
    return MediumSpec(thickness, sigma_t, albedo, phase, grey)
