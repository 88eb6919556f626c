"""Phase functions for the media of layered stacks (used by the layered random walk).

Interface (stable; every class below implements it)
----------------------------------------------------
Directions are **propagation directions**: ``d_in`` is the direction light travels before the
scattering event, ``d_out`` the one after, so forward scattering means d_out ≈ d_in and
cos θ = d_in·d_out. (This differs from BSDFs, whose two directions point away from the surface;
a walk coming from an interface with outgoing BSDF direction ``wo`` calls ``phase.sample(wo)``.)
All direction arrays are (n, 3) float64 unit vectors in the layer frame (x = UV tangent,
z = stack normal, up).

    phase.eval(d_in, d_out)  -> (n,)   p(d_in → d_out), normalised: ∫ p(d_in → ω) dω = 1
    phase.pdf(d_in, d_out)   -> (n,)   the density ``sample`` draws d_out with (= eval: all exact)
    phase.sample(d_in, rng)  -> PhaseSample(d_out (n, 3), weight (n,), pdf (n,))
                                        weight = p/pdf: 1, or 0 where sampling failed
    phase.sigma_scale(d)     -> (n,)   direction-dependent extinction factor:
                                        σt(ω) = density · sigma_scale(ω); 1 for non-microflake phases
    phase.take(idx)          -> Phase  the lanes idx (index array or boolean mask)
    phase.directional        class flag: sigma_scale is not identically 1
    phase.stats              SamplingStats(samples, failures, iterations), shared with take()s

Parameters are per lane or constant: scalars have shape () (constant) or (n,), vectors (1, 3)
or (n, 3) (see ``materials.base.lanes``). A constant phase serves any number of lanes.
``rng`` is a ``numpy.random.Generator``.

Reciprocity. The phases of the scattering angle alone (simple.py) satisfy p(a → b) = p(−b → −a).
The microflake phases (fiber, SGGX) satisfy σ(a) p(a → b) = σ(b) p(−b → −a) instead
(σ = sigma_scale): the reciprocal quantity is σs·p, which is what the position-free path
contribution contains.

Classes
-------
One per row of ``backend/layered/phase_schema.py`` (its ``type_name`` is the row's name; the
parser finds it by that): the phases of the scattering angle in simple.py (``Isotropic()``,
``HenyeyGreenstein(g)``, g clamped to ±0.999, …), ``MicroflakeFiber(stddev, orientation)`` in
fiber.py (Guo et al.'s Gaussian fiber flakes; stddev clamped to [1e-3, 4]), ``SGGX(s6)`` /
``SGGX.fiber(axis, roughness)`` / ``SGGX.flake(normal, roughness)`` in sggx.py.
Scene parsing: ``parse_phase(node) -> PhaseSpec`` with ``spec.bind(uv) -> Phase``.
"""
from .base import Phase, PhaseSample, SamplingStats
from .fiber import MicroflakeFiber, fiber_sigma
from .parse import PhaseSpec, parse_phase
from .sggx import SGGX
from .simple import HenyeyGreenstein, Isotropic, VonMisesFisher

__all__ = [
    "Phase", "PhaseSample", "SamplingStats", "Isotropic", "HenyeyGreenstein", "VonMisesFisher",
    "MicroflakeFiber", "SGGX", "fiber_sigma", "PhaseSpec", "parse_phase",
]
