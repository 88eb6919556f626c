"""The phase functions as a scene file and Blender's stack editor see them: one row per kind with
its parameters (scene-file key, range, default, Blender property), bpy-free and NumPy-free.

Read by the scene parser (``backend/layered/phase/parse.py``: one generic parser per row), the stack table
(``backend/layered/stack_table.py``: which parameter fills the medium row's scalar slot ``a`` and
its vector slot ``v``) and the add-on (``addon/props/layer.py`` makes the properties,
``addon/export/stack.py`` writes the scene file, ``addon/ui/material.py`` draws the panel,
``addon/presets/convert.py`` reads presets back). A new phase function adds its row here; its
maths lives in backend/kernels/layered/phase.py (per lane) and its NumPy class in
backend/layered/phase/ (its ``type_name`` is the row's ``name``). This module sits outside that
package so that the add-on imports it alone.

Blender stores an enum by its number and a property by its name: ``number`` and ``prop`` are
what saved .blend files hold and never change.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..kernels.layered.phase_layout import S_MAX


@dataclass(frozen=True)
class Param:
    key: str                          # the scene file's key
    prop: str                         # LaminaLayer's property (shared by kinds that share it)
    kind: str                         # "scalar" (texturable number), "axis" (texturable 3-vector), "choice"
    label: str
    description: str
    slot: str = ""                    # "a" (the medium row's scalar) or "v" (its vector); "" none
    default: object = None            # scene-file default; None: required
    lo: float | None = None           # scene-file range (the loader's message names it)
    hi: float | None = None
    lo_open: bool = False
    ui_default: object = None         # Blender's default (None: ``default``)
    ui: dict = field(default_factory=dict)      # Blender property options (min, max, subtype, …)
    choices: tuple = ()               # "choice": (value, label, description) per option
    defaults_by: tuple = ()           # (choice key, {choice value: default}) for a default that depends on a choice
    labels_by: tuple = ()             # (choice key, {choice value: panel label})
    texture_prop: str = ""            # "axis": LaminaLayer's image property that replaces the vector


@dataclass(frozen=True)
class PhaseKind:
    name: str                         # scene-file "type"
    enum: str                         # Blender's enum identifier
    number: int                       # Blender's enum number
    label: str
    description: str
    params: tuple = ()
    directional: bool = False         # σt depends on the direction (microflake media)
    summary: str = ""                 # the stack list's short text, formatted with the properties


_AXIS_DOC = ("Fibre axis (or SGGX flake normal) in the shading frame (x = UV tangent, z = normal); "
             "the renderer normalises it")
_AXIS_UI = {"size": 3, "subtype": "XYZ", "soft_min": -1.0, "soft_max": 1.0}

PHASES: tuple[PhaseKind, ...] = (
    PhaseKind("isotropic", "ISOTROPIC", 0, "Isotropic", "Scatters equally in all directions",
              summary="iso"),
    PhaseKind("hg", "HG", 1, "Henyey-Greenstein", "Forward (g > 0) or backward (g < 0) scattering",
              (Param("g", "hg_g", "scalar", "Anisotropy g",
                     "Henyey-Greenstein mean cosine: > 0 forward, < 0 backward scattering",
                     slot="a", lo=-1.0, hi=1.0, ui_default=0.0,
                     ui={"min": -0.999, "max": 0.999, "subtype": "FACTOR"}),),
              summary="g {hg_g:.2g}"),
    PhaseKind("microflake", "MICROFLAKE", 2, "Microflake (fibre)",
              "Oriented flakes/fibres (Guo et al. 2018): anisotropic scattering and extinction",
              (Param("stddev", "flake_stddev", "scalar", "Flake Spread",
                     "Standard deviation of the microflake/fibre orientation distribution",
                     slot="a", lo=0.0, hi=S_MAX, lo_open=True, ui_default=0.05,
                     ui={"min": 0.001, "max": 1.0, "precision": 3}),
               Param("orientation", "flake_orientation", "axis", "Axis", _AXIS_DOC, slot="v",
                     default=(1.0, 0.0, 0.0), ui=_AXIS_UI, texture_prop="orientation_texture")),
              directional=True, summary="fibres"),
    PhaseKind("vmf", "VMF", 3, "von Mises-Fisher", "A forward lobe of concentration κ",
              (Param("kappa", "vmf_kappa", "scalar", "Concentration κ",
                     "von Mises-Fisher concentration: 0 = isotropic, larger = narrower forward lobe",
                     slot="a", lo=0.0, ui_default=10.0, ui={"min": 0.0, "soft_max": 1000.0}),),
              summary="κ {vmf_kappa:.3g}"),
    PhaseKind("sggx", "SGGX", 4, "SGGX", "SGGX specular microflakes (fibres or flakes) with a roughness",
              (Param("shape", "sggx_shape", "choice", "Shape", "Fibres along the axis or flakes normal to it",
                     default="fiber", choices=(("fiber", "Fibres", "Fibres along the axis"),
                                               ("flake", "Flakes", "Flakes whose normal is the axis"))),
               Param("orientation", "flake_orientation", "axis", "Axis", _AXIS_DOC, slot="v",
                     default=(1.0, 0.0, 0.0), ui=_AXIS_UI, texture_prop="orientation_texture",
                     defaults_by=("shape", {"flake": (0.0, 0.0, 1.0)}),
                     labels_by=("shape", {"flake": "Normal"})),
               Param("roughness", "sggx_roughness", "scalar", "Roughness",
                     "SGGX roughness: 1 = isotropic, small = aligned fibres/flakes",
                     slot="a", lo=0.0, hi=1.0, lo_open=True, ui_default=0.3,
                     ui={"min": 0.001, "max": 1.0, "subtype": "FACTOR"})),
              directional=True, summary="sggx"),
    PhaseKind("rayleigh", "RAYLEIGH", 5, "Rayleigh",
              "Particles much smaller than the wavelength: forward and backward alike, 3(1 + cos²θ)/16π",
              summary="rayleigh"),
)

BY_NAME = {k.name: k for k in PHASES}
BY_ENUM = {k.enum: k for k in PHASES}


def default_of(param: Param, values: dict):
    """A parameter's scene-file default given the kind's other values (its choices)."""
    if param.defaults_by:
        key, table = param.defaults_by
        return table.get(values.get(key), param.default)
    return param.default


def label_of(param: Param, values: dict) -> str:
    if param.labels_by:
        key, table = param.labels_by
        return table.get(values.get(key), param.label)
    return param.label
