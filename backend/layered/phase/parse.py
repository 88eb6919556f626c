"""Scene-file parsing of phase functions (``layered`` → ``media[i].phase``; docs/materials.md).

``parse_phase(node)`` returns a :class:`PhaseSpec`: the scene-level description holding texturable
parameters (``backend.textures.Param``). ``spec.bind(uv)`` evaluates the textures at n shading
points and returns a lane-bound :class:`~.base.Phase` (constants stay constants).

Vector parameters (``orientation``) are given as a list of 3 numbers in the layer frame
(x = UV tangent, y = bitangent, z = stack normal) or as an RGB texture encoded like a normal map
(value · 2 − 1); both are normalised per lane.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ...textures import Param
from .base import Phase
from .fiber import S_MAX, MicroflakeFiber
from .sggx import SGGX, is_positive_definite, preset_matrix
from .simple import HenyeyGreenstein, Isotropic, VonMisesFisher


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


def _orientation(node, default) -> Param:
    p = node.param("orientation", default, channels=3, lo=None, color=False)
    if p.is_constant and not np.any(p.bind(None)):
        raise node.fail("expected a non-zero vector", "orientation")
    return p


def _isotropic(node) -> PhaseSpec:
    return PhaseSpec("isotropic", Isotropic, {}, False)


def _hg(node) -> PhaseSpec:
    g = node.param("g", lo=-1.0, hi=1.0)
    return PhaseSpec("hg", HenyeyGreenstein, {"g": g}, False)


def _vmf(node) -> PhaseSpec:
    kappa = node.param("kappa", lo=0.0)
    return PhaseSpec("vmf", VonMisesFisher, {"kappa": kappa}, False)


def _microflake(node) -> PhaseSpec:
    stddev = node.param("stddev", lo=0.0, hi=S_MAX, lo_open=True)
    orientation = _orientation(node, [1.0, 0.0, 0.0])
    return PhaseSpec("microflake", MicroflakeFiber, {"stddev": stddev, "orientation": orientation},
                     True, {"orientation": _normal_map_decode})


def _sggx(node) -> PhaseSpec:
    if node.has("matrix"):
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
    shape = node.string("shape", "fiber", choices=("fiber", "flake"))
    orientation = _orientation(node, [1.0, 0.0, 0.0] if shape == "fiber" else [0.0, 0.0, 1.0])
    roughness = node.param("roughness", lo=0.0, hi=1.0, lo_open=True)

    def make(orientation, roughness):
        return SGGX(preset_matrix(shape, orientation, roughness))

    return PhaseSpec("sggx", make, {"orientation": orientation, "roughness": roughness}, True,
                     {"orientation": _normal_map_decode}, settings={"shape": shape})


PARSERS = {
    "isotropic": _isotropic,
    "hg": _hg,
    "vmf": _vmf,
    "microflake": _microflake,
    "sggx": _sggx,
}


def parse_phase(node) -> PhaseSpec:
    """Parse a phase-function object (a ``scene.reader.Node``); raises SceneError naming the field."""
    from ...scene.reader import dispatch
    return dispatch(node, PARSERS)
