"""Materials as a typed parameter table, and per-lane dispatch to the BSDF kernels.

``MaterialTable`` (one row per scene material):
  kind      int32   DIFFUSE, CONDUCTOR, DIELECTRIC, BLACK (emission only: reflects nothing),
                    LAYERED (a multi-interface layered stack evaluated by the random walk: its id
                    in the stack table (kernels/layered/table.py) sits in slot LAYER_ID; shaded
                    per lane by kernels/layered/batch.shade_lane), COATED_DIFFUSE (a layered
                    stack in closed form: kernels/bsdf/coated_diffuse.py, its table block at
                    ``tables[values[CD_TAB]]``), TABULATED (a uniform stack solved into a table:
                    kernels/bsdf/tabulated.py, its block at ``tables[values[TB_TAB]]``), MIX or ADD (a Mix / Add Shader: the
                    integrator picks one component row per hit, ``_resolve_mix``)
  dist, masking     microfacet codes (kernels/microfacet.py)
  two_sided bool    reflection-only materials are seen from both sides (the integrator turns the
                    frame towards the viewer); transmissive ones are not flipped
  emits     bool    the material has an ``emission``
  emit_front bool   it emits from the front side only (counter-clockwise winding), else both
  values    float64 (M, NSLOT), tex int32 (M, NSLOT): texturable parameters (kernels/params.py),
                    an RGB parameter takes three consecutive slots and its texture id sits in the
                    first. Slot layout below (EMISSION and the normal map are common to every kind).
  nmode     int32   the material's normal map (materials/normal.py): 0 none, 1 a constant
                    normal (slots N_MAP, unit), 2 a texture (slots N_MAP: RGB · 2 − 1); its
                    strength in slot N_STRENGTH (kernels/integrator.py ``_mapped_normal``)
  bump      bool    a bump map (materials/normal.Bump): height texture × distance in slot
                    B_HEIGHT, strength in B_STRENGTH (kernels/integrator.py ``_bumped_normal``)

Per lane, ``bind`` evaluates a row's parameters at a UV into a fixed 12-tuple ``p`` (so every
kind returns the same Numba type). Each kind's slots and its 12-tuple are its kernel module's
(kernels/bsdf/<kind>.py, "binding": ``params`` packs it, ``eval_pdf_p`` / ``sample_p`` /
``albedo_p`` read it); ``eval_pdf`` / ``sample`` / ``albedo`` here only dispatch on kind.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .bsdf import coated_diffuse, conductor, dielectric, diffuse, tabulated
from .jit import inlined, kernel
from .microfacet import DISTRIBUTION_CODES, MASKING_CODES
from .params import ParamPacker, param_rgb, param_scalar

DIFFUSE, CONDUCTOR, DIELECTRIC, BLACK, LAYERED, MIX, ADD, COATED_DIFFUSE, TABULATED = 0, 1, 2, 3, 4, 5, 6, 7, 8
KINDS = {DIFFUSE: "diffuse", CONDUCTOR: "conductor", DIELECTRIC: "dielectric", BLACK: "black",
         LAYERED: "layered", MIX: "mix", ADD: "add", COATED_DIFFUSE: "coated_diffuse", TABULATED: "tabulated"}
#: The kinds with a BSDF of their own, and which dispatcher below answers which kinds (a layered
#: stack's walk, mixes and black surfaces are the integrator's own): tests/test_kind_dispatch.py
#: checks each dispatcher's branches against this, so a new kind cannot miss one.
BSDF_KINDS = (DIFFUSE, CONDUCTOR, DIELECTRIC, COATED_DIFFUSE, TABULATED)
ANSWERS = {"bind": BSDF_KINDS, "eval_pdf": BSDF_KINDS, "sample": BSDF_KINDS, "albedo": BSDF_KINDS,
           "is_delta_only": (CONDUCTOR, DIELECTRIC, BLACK), "is_mix": (MIX, ADD),
           "is_stack": (LAYERED, COATED_DIFFUSE, TABULATED), "chosen_reflectance": (DIELECTRIC, COATED_DIFFUSE, TABULATED),
           "sharp_top": (COATED_DIFFUSE, TABULATED)}
NSLOT = 22
EMISSION = 0                 # RGB, every kind
N_MAP, N_STRENGTH = 16, 19   # every kind: the normal map (RGB) and its strength
B_HEIGHT, B_STRENGTH = 20, 21   # every kind: the bump map's height × distance and its strength
# Each BSDF kind's slots are in its kernel module (kernels/bsdf/*.py, "binding"); the names here
# are for the Python materials that pack them.
COLOR = diffuse.COLOR
ETA, K, TINT, AU, AV = conductor.ETA, conductor.K, conductor.TINT, conductor.AU, conductor.AV
D_ETA, D_TINT, D_AU, D_AV = dielectric.ETA, dielectric.TINT, dielectric.AU, dielectric.AV
CD_ETA, CD_AU, CD_AV, CD_RHO, CD_TAB = (coated_diffuse.ETA, coated_diffuse.AU, coated_diffuse.AV,
                                        coated_diffuse.RHO, coated_diffuse.TAB)
TB_TAB, TB_RHO = tabulated.TAB, tabulated.RHO
LAYER_ID = 3                 # layered: the stack's row in the stack table
MIX_FACTOR, MIX_N, MIX_C0 = 3, 4, 5   # mix/add (materials/mix.py): factor, count, component rows (≤ 8)

MaterialTable = namedtuple("MaterialTable", ["kind", "dist", "masking", "two_sided", "emits",
                                             "values", "tex", "emit_front", "nmode", "bump", "tables"])


class TableBuilder:
    """The precomputed blocks of a scene's deterministic layered forms, one flat float64 array
    (the same block added twice is stored once)."""

    def __init__(self):
        self._blocks: list = []
        self._offsets: dict = {}
        self._size = 0

    def add(self, block: np.ndarray) -> int:
        key = id(block)
        if key not in self._offsets:
            self._offsets[key] = self._size
            self._blocks.append(block)
            self._size += block.size
        return self._offsets[key]

    def array(self) -> np.ndarray:
        if not self._blocks:
            return np.zeros(1)
        return np.ascontiguousarray(np.concatenate(self._blocks))


class MaterialRow:
    """One material's row while the table is built (see ``Material.pack``)."""

    def __init__(self, packer: ParamPacker, stacks=None, tables: TableBuilder | None = None):
        self.packer = packer
        self.stacks = stacks          # the scene's layered stacks (layered/stack_table.StackBuilder)
        self.tables = tables if tables is not None else TableBuilder()   # deterministic forms' blocks
        self.kind = BLACK
        self.dist = 0
        self.masking = 0
        self.two_sided = True
        self.emits = False
        self.emit_front = False
        self.values = np.zeros(NSLOT)
        self.tex = np.full(NSLOT, -1, np.int32)
        self.nmode = 0
        self.bump = False

    def set(self, slot: int, param, channels: int, factor=1.0) -> None:
        values, tex = self.packer.pack(param, channels, factor)
        self.values[slot:slot + channels] = values
        self.tex[slot] = tex

    def microfacet(self, distribution: str, masking: str) -> None:
        self.dist = DISTRIBUTION_CODES[distribution]
        self.masking = MASKING_CODES[masking]


def build_material_table(materials: list, packer: ParamPacker, stacks=None) -> MaterialTable:
    """``stacks``: a layered/stack_table.StackBuilder collecting the layered stacks (their rows
    get kind LAYERED and the stack id)."""
    rows = []
    tables = TableBuilder()
    for m in materials:
        row = MaterialRow(packer, stacks, tables)
        m.pack(row)
        row.two_sided = bool(m.two_sided)
        if getattr(m, "emission", None) is not None:
            row.set(EMISSION, m.emission, 3)
            row.emits = True
            row.emit_front = bool(getattr(m, "emission_front_only", False))
        _pack_normal_map(row, getattr(m, "normal_map", None), getattr(m, "normal_strength", 1.0))
        bump = getattr(m, "bump", None)
        if bump is not None:
            row.set(B_HEIGHT, bump.height, 1, bump.distance)
            row.values[B_STRENGTH] = bump.strength
            row.bump = True
        rows.append(row)
    if not rows:
        rows.append(MaterialRow(packer, stacks, tables))
    return MaterialTable(np.array([r.kind for r in rows], np.int32), np.array([r.dist for r in rows], np.int32),
                         np.array([r.masking for r in rows], np.int32), np.array([r.two_sided for r in rows]),
                         np.array([r.emits for r in rows]), np.stack([r.values for r in rows]),
                         np.stack([r.tex for r in rows]), np.array([r.emit_front for r in rows]),
                         np.array([r.nmode for r in rows], np.int32), np.array([r.bump for r in rows]),
                         tables.array())


@inlined
def is_mix(kind):
    return kind == MIX or kind == ADD


@inlined
def is_stack(kind):
    """A layered stack, whatever evaluates it (its reflection's ray type is the stack's)."""
    return kind == LAYERED or kind == COATED_DIFFUSE or kind == TABULATED


def _pack_normal_map(row: MaterialRow, normal, strength: float) -> None:
    """A material's normal map (materials/normal.NormalParam or None) into its row."""
    row.values[N_STRENGTH] = strength
    if normal is None:
        return
    if normal.texture:
        row.set(N_MAP, normal.param, 3)
        row.nmode = 2
        return
    n = normal.bind(None)                  # unit, kept above the surface; None: the normal itself
    if n is not None:
        row.values[N_MAP:N_MAP + 3] = n[:, 0]
        row.nmode = 1


@inlined
def _rgb(mt, tx, m, slot, u, v):
    # Elements, not a slice: a view would take a reference (an atomic increment) per call.
    vals = mt.values
    return param_rgb(tx, (vals[m, slot], vals[m, slot + 1], vals[m, slot + 2]), mt.tex[m, slot], u, v)


@inlined
def _scalar(mt, tx, m, slot, u, v):
    return param_scalar(tx, mt.values[m, slot], mt.tex[m, slot], u, v)


@inlined
def emission(mt, tx, m, u, v):
    """Emitted radiance [W m⁻² sr⁻¹] of material m at (u, v) (the caller checks the side of a
    front-only emitter: ``emit_front``)."""
    if not mt.emits[m]:
        return (0.0, 0.0, 0.0)
    return _rgb(mt, tx, m, EMISSION, u, v)


@inlined
def bind(mt, tx, m, u, v):
    """The 12-tuple of lane parameters (see the module docstring): each kind's slots read here,
    packed by its kernel module's ``params``."""
    kind = mt.kind[m]
    if kind == DIFFUSE:
        return diffuse.params(_rgb(mt, tx, m, diffuse.COLOR, u, v))
    if kind == CONDUCTOR:
        return conductor.params(_rgb(mt, tx, m, conductor.ETA, u, v), _rgb(mt, tx, m, conductor.K, u, v),
                                _rgb(mt, tx, m, conductor.TINT, u, v), _scalar(mt, tx, m, conductor.AU, u, v),
                                _scalar(mt, tx, m, conductor.AV, u, v))
    if kind == DIELECTRIC:
        return dielectric.params(_scalar(mt, tx, m, dielectric.ETA, u, v), _rgb(mt, tx, m, dielectric.TINT, u, v),
                                 _scalar(mt, tx, m, dielectric.AU, u, v), _scalar(mt, tx, m, dielectric.AV, u, v))
    if kind == COATED_DIFFUSE:
        au = _scalar(mt, tx, m, coated_diffuse.AU, u, v)
        av = _scalar(mt, tx, m, coated_diffuse.AV, u, v)
        c = _rgb(mt, tx, m, coated_diffuse.RHO, u, v)
        return coated_diffuse.params(mt.values[m, coated_diffuse.ETA], au, av, c, mt.values[m, coated_diffuse.TAB])
    if kind == TABULATED:
        return tabulated.params(mt.values[m, tabulated.TAB], _rgb(mt, tx, m, tabulated.RHO, u, v))
    return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@kernel
def is_delta_only(kind, p):
    """Every lobe is a delta (no light sampling needed): smooth metals and glass, black."""
    if kind == CONDUCTOR:
        return conductor.delta_only_p(p)
    if kind == DIELECTRIC:
        return dielectric.delta_only_p(p)
    return kind == BLACK


@inlined
def chosen_reflectance(T, kind, p, wi):
    """Where ``sample`` takes a delta mirror only by a random number — smooth glass seen from
    outside, the smooth top of a coated kind — what that mirror returns on average (its Fresnel
    reflectance); 0 elsewhere (no delta mirror, or one taken every time: a smooth metal)."""
    if kind == DIELECTRIC:
        return dielectric.smooth_reflectance_p(p, wi)
    if kind == COATED_DIFFUSE:
        return coated_diffuse.smooth_reflectance_p(p, wi)
    if kind == TABULATED:
        return tabulated.smooth_reflectance_p(T, p, wi)
    return 0.0


@inlined
def sharp_top(T, kind, dist, p, wi, u0, u1):
    """A coated kind whose top is rough but sharp (0 < α ≤ SHARP_ALPHA, kernels/bsdf/
    coated_diffuse.py): (the probability w_s that ``sample`` takes the top's lobe at wi — its
    choice is u2 < w_s — and a direction from that lobe alone, by u0, u1); w_s 0 elsewhere."""
    if kind == COATED_DIFFUSE:
        return coated_diffuse.sharp_top_p(T, p, dist, wi, u0, u1)
    if kind == TABULATED:
        return tabulated.sharp_top_p(T, p, wi, u0, u1)
    return 0.0, (0.0, 0.0, 1.0)


@kernel
def eval_pdf(T, kind, dist, masking, p, mode, wi, wo):
    """(f·|cos θo| RGB, pdf) of the non-delta part; T: the material table's ``tables``."""
    if kind == DIFFUSE:
        return diffuse.eval_pdf_p(p, wi, wo)
    if kind == CONDUCTOR:
        return conductor.eval_pdf_p(p, dist, masking, wi, wo)
    if kind == DIELECTRIC:
        return dielectric.eval_pdf_p(p, dist, masking, mode, wi, wo)
    if kind == COATED_DIFFUSE:
        return coated_diffuse.eval_pdf_p(T, p, dist, masking, wi, wo)
    if kind == TABULATED:
        return tabulated.eval_pdf_p(T, p, wi, wo)
    return (0.0, 0.0, 0.0), 0.0


@kernel
def sample(T, kind, dist, masking, p, mode, wi, u0, u1, u2):
    """(wo, weight RGB, pdf, is_delta); weight 0 ends the path."""
    if kind == DIFFUSE:
        return diffuse.sample_p(p, wi, u0, u1)
    if kind == CONDUCTOR:
        return conductor.sample_p(p, dist, masking, wi, u0, u1)
    if kind == DIELECTRIC:
        return dielectric.sample_p(p, dist, masking, mode, wi, u0, u1, u2)
    if kind == COATED_DIFFUSE:
        return coated_diffuse.sample_p(T, p, dist, masking, wi, u0, u1, u2)
    if kind == TABULATED:
        return tabulated.sample_p(T, p, wi, u0, u1, u2)
    return (0.0, 0.0, 1.0 if wi[2] >= 0.0 else -1.0), (0.0, 0.0, 0.0), 0.0, False


@kernel
def albedo(T, kind, p, wi):
    """RGB reflectance estimate for the denoising AOV (a stack's: its directional albedo at wi)."""
    if kind == DIFFUSE:
        return diffuse.albedo_p(p)
    if kind == CONDUCTOR:
        return conductor.albedo_p(p)
    if kind == DIELECTRIC:
        return dielectric.albedo_p(p)
    if kind == COATED_DIFFUSE:
        return coated_diffuse.albedo_p(T, p, wi[2])
    if kind == TABULATED:
        return tabulated.albedo_p(T, p, wi[2])
    return (0.0, 0.0, 0.0)
