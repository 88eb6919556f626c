"""Scene-file parsing of phase functions (``layered`` → ``media[i].phase``; docs/materials.md).

``parse_phase(node)`` returns a :class:`PhaseSpec`: the scene-level description holding texturable
parameters (``backend.textures.Param``). ``spec.bind(uv)`` evaluates the textures at n shading
points and returns a lane-bound :class:`~.base.Phase` (constants stay constants).

Vector parameters (``orientation``) are given as a list of 3 numbers in the layer frame
(x = UV tangent, y = bitangent, z = stack normal) or as an RGB texture encoded like a normal map
(value · 2 − 1); both are normalised per lane.
"""
from __future__ import annotations

import functools
from typing import Callable

import numpy as np

from ...textures import Param
from .base import Phase
from . import fiber, simple  # noqa: F401 (their classes register by subclassing Phase)
from ..phase_schema import BY_NAME, PHASES, PhaseKind, default_of
from .sggx import SGGX, is_positive_definite


class PhaseSpec:
    """A parsed phase function: a factory plus its texturable parameters."""

    def __init__(self, type_name: str, factory: Callable[..., Phase], params: dict[str, Param],
                 directional: bool, decode: dict[str, Callable] | None = None,
                 settings: dict | None = None):
        self.type_name = type_name
        self.factory = factory
        self.params = params
        self.directional = directional
        self.decode = decode or {}
        self.settings = settings or {}   # untexturable choices (SGGX shape or matrix)

    @property
    def uses_textures(self) -> bool:
        return any(not p.is_constant for p in self.params.values())

    def bind(self, uv: np.ndarray) -> Phase:
        values = {}
        for name, p in self.params.items():
            v = p.bind(uv)
            if name in self.decode and not p.is_constant:
                v = self.decode[name](v)
            values[name] = v
        return self.factory(**values)

    def __repr__(self) -> str:
        return f"PhaseSpec({self.type_name!r})"


def _normal_map_decode(v: np.ndarray) -> np.ndarray:
    return 2.0 * v - 1.0


def _orientation(node, default, key: str = "orientation") -> Param:
    p = node.param(key, default, channels=3, lo=None, color=False)
    if p.is_constant and not np.any(p.bind(None)):
        raise node.fail("expected a non-zero vector", key)
    return p


def _classes() -> dict:
    """The Phase classes by scene-file type (every subclass defined in this package)."""
    found, todo = {}, list(Phase.__subclasses__())
    while todo:
        cls = todo.pop()
        todo.extend(cls.__subclasses__())
        if cls.type_name:
            found.setdefault(cls.type_name, cls)
    return found


def _parser(kind: PhaseKind):
    """The scene-file parser of one schema row (schema.py): choices first (a default may depend on
    them), then the texturable parameters with the row's ranges."""
    def parse(node) -> PhaseSpec:
        settings, params, decode = {}, {}, {}
        for p in kind.params:
            if p.kind == "choice":
                settings[p.key] = node.string(p.key, p.default, choices=tuple(c[0] for c in p.choices))
            elif p.kind == "axis":
                params[p.key] = _orientation(node, list(default_of(p, settings)), p.key)
                decode[p.key] = _normal_map_decode
            else:
                default = () if p.default is None else (p.default,)
                params[p.key] = node.param(p.key, *default, lo=p.lo, hi=p.hi, lo_open=p.lo_open)
        return _spec(kind, settings, params, decode)
    return parse


def _spec(kind: PhaseKind, settings: dict, params: dict, decode: dict) -> PhaseSpec:
    cls = _classes()[kind.name]
    return PhaseSpec(kind.name, functools.partial(cls.from_params, settings), params, kind.directional,
                     decode, settings=settings)


def isotropic_spec() -> PhaseSpec:
    """What a medium without a ``phase`` gets: the same as ``{"type": "isotropic"}``."""
    return _spec(BY_NAME["isotropic"], {}, {}, {})


def _sggx(node) -> PhaseSpec:
    """SGGX takes either the schema's shape, orientation and roughness or an explicit matrix."""
    if not node.has("matrix"):
        return _parser(BY_NAME["sggx"])(node)
    m = node.vector("matrix", 6)
    if not is_positive_definite(m):
        raise node.fail("expected a positive-definite matrix [Sxx, Syy, Szz, Sxy, Sxz, Syz]",
                        "matrix")
    node.ignore("shape", "orientation", "roughness")
    for key in ("shape", "orientation", "roughness"):
        if node.has(key):
            raise node.fail("not allowed together with \"matrix\"", key)
    const = np.asarray(m, dtype=np.float64)
    return PhaseSpec("sggx", lambda: SGGX(const), {}, True, settings={"matrix": const})


PARSERS = {kind.name: _parser(kind) for kind in PHASES}
PARSERS["sggx"] = _sggx


def parse_phase(node) -> PhaseSpec:
    """Parse a phase-function object (a ``scene.reader.Node``); raises SceneError naming the field."""
    from ...scene.reader import dispatch
    return dispatch(node, PARSERS)
