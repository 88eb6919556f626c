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
kind returns the same Numba type): diffuse (colour); conductor (eta, k, tint, αu, αv, smooth);
dielectric (eta, tint, αu, αv, smooth); coated diffuse (eta, αu, αv, smooth, body colour, table
offset); tabulated (table offset, a textured body's colour). ``eval_pdf`` / ``sample`` / ``albedo`` dispatch on kind.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .bsdf import coated_diffuse, conductor, dielectric, diffuse, tabulated
from .jit import inlined, kernel
from .microfacet import ALPHA_MIN, DISTRIBUTION_CODES, MASKING_CODES
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
           "is_stack": (LAYERED, COATED_DIFFUSE, TABULATED)}
NSLOT = 22
EMISSION = 0                 # RGB, every kind
N_MAP, N_STRENGTH = 16, 19   # every kind: the normal map (RGB) and its strength
B_HEIGHT, B_STRENGTH = 20, 21   # every kind: the bump map's height × distance and its strength
COLOR = 3                    # diffuse: RGB albedo
ETA, K, TINT, AU, AV = 3, 6, 9, 12, 13         # conductor: relative eta, k (RGB), tint, α
D_ETA, D_TINT, D_AU, D_AV = 3, 4, 7, 8           # dielectric: relative eta, transmission colour, α
LAYER_ID = 3                 # layered: the stack's row in the stack table
MIX_FACTOR, MIX_N, MIX_C0 = 3, 4, 5   # mix/add (materials/mix.py): factor, count, component rows (≤ 8)
CD_ETA, CD_AU, CD_AV, CD_RHO, CD_TAB = 3, 4, 5, 6, 9   # coated diffuse: relative eta, α, body colour, table
TB_TAB, TB_RHO = 3, 4        # tabulated stack: its table block, a textured body's colour (RGB)

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
    """The 12-tuple of lane parameters (see the module docstring)."""
    kind = mt.kind[m]
    if kind == DIFFUSE:
        c = _rgb(mt, tx, m, COLOR, u, v)
        return (c[0], c[1], c[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    if kind == CONDUCTOR:
        e = _rgb(mt, tx, m, ETA, u, v)
        k = _rgb(mt, tx, m, K, u, v)
        t = _rgb(mt, tx, m, TINT, u, v)
        au = _scalar(mt, tx, m, AU, u, v)
        av = _scalar(mt, tx, m, AV, u, v)
        smooth = 1.0 if (au <= 0.0 and av <= 0.0) else 0.0
        return (e[0], e[1], e[2], k[0], k[1], k[2], t[0], t[1], t[2],
                max(au, ALPHA_MIN), max(av, ALPHA_MIN), smooth)
    if kind == DIELECTRIC:
        # A texture may hold 0 (texels are clamped to the range's closed end): keep the index
        # positive so 1/eta stays finite.
        eta = max(_scalar(mt, tx, m, D_ETA, u, v), 1e-4)
        t = _rgb(mt, tx, m, D_TINT, u, v)
        au = _scalar(mt, tx, m, D_AU, u, v)
        av = _scalar(mt, tx, m, D_AV, u, v)
        smooth = 1.0 if (au <= 0.0 and av <= 0.0) else 0.0
        return (eta, t[0], t[1], t[2], max(au, ALPHA_MIN), max(av, ALPHA_MIN), smooth,
                0.0, 0.0, 0.0, 0.0, 0.0)
    if kind == COATED_DIFFUSE:
        au = _scalar(mt, tx, m, CD_AU, u, v)
        av = _scalar(mt, tx, m, CD_AV, u, v)
        c = _rgb(mt, tx, m, CD_RHO, u, v)
        smooth = 1.0 if (au <= 0.0 and av <= 0.0) else 0.0
        return (mt.values[m, CD_ETA], max(au, ALPHA_MIN), max(av, ALPHA_MIN), smooth, c[0], c[1], c[2],
                mt.values[m, CD_TAB], 0.0, 0.0, 0.0, 0.0)
    if kind == TABULATED:
        c = _rgb(mt, tx, m, TB_RHO, u, v)
        return (mt.values[m, TB_TAB], c[0], c[1], c[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@kernel
def is_delta_only(kind, p):
    """Every lobe is a delta (no light sampling needed): smooth metals and glass, black."""
    if kind == CONDUCTOR:
        return p[11] > 0.0
    if kind == DIELECTRIC:
        return p[6] > 0.0
    return kind == BLACK


@kernel
def eval_pdf(T, kind, dist, masking, p, mode, wi, wo):
    """(f·|cos θo| RGB, pdf) of the non-delta part; T: the material table's ``tables``."""
    if kind == DIFFUSE:
        return diffuse.eval_pdf((p[0], p[1], p[2]), wi, wo)
    if kind == CONDUCTOR:
        return conductor.eval_pdf((p[0], p[1], p[2]), (p[3], p[4], p[5]), (p[6], p[7], p[8]),
                                  p[9], p[10], p[11] > 0.0, dist, masking, wi, wo)
    if kind == DIELECTRIC:
        return dielectric.eval_pdf(p[0], (p[1], p[2], p[3]), p[4], p[5], p[6] > 0.0, dist, masking,
                                   mode, wi, wo)
    if kind == COATED_DIFFUSE:
        return coated_diffuse.eval_pdf(T, int(p[7]), p[0], p[1], p[2], p[3] > 0.0, (p[4], p[5], p[6]),
                                       dist, masking, wi, wo)
    if kind == TABULATED:
        return tabulated.eval_pdf(T, int(p[0]), (p[1], p[2], p[3]), wi, wo)
    return (0.0, 0.0, 0.0), 0.0


@kernel
def sample(T, kind, dist, masking, p, mode, wi, u0, u1, u2):
    """(wo, weight RGB, pdf, is_delta); weight 0 ends the path."""
    if kind == DIFFUSE:
        return diffuse.sample((p[0], p[1], p[2]), wi, u0, u1)
    if kind == CONDUCTOR:
        return conductor.sample((p[0], p[1], p[2]), (p[3], p[4], p[5]), (p[6], p[7], p[8]),
                                p[9], p[10], p[11] > 0.0, dist, masking, wi, u0, u1)
    if kind == DIELECTRIC:
        return dielectric.sample(p[0], (p[1], p[2], p[3]), p[4], p[5], p[6] > 0.0, dist, masking,
                                 mode, wi, u0, u1, u2)
    if kind == COATED_DIFFUSE:
        return coated_diffuse.sample(T, int(p[7]), p[0], p[1], p[2], p[3] > 0.0, (p[4], p[5], p[6]),
                                     dist, masking, wi, u0, u1, u2)
    if kind == TABULATED:
        return tabulated.sample(T, int(p[0]), (p[1], p[2], p[3]), wi, u0, u1, u2)
    return (0.0, 0.0, 1.0 if wi[2] >= 0.0 else -1.0), (0.0, 0.0, 0.0), 0.0, False


@kernel
def albedo(T, kind, p, wi):
    """RGB reflectance estimate for the denoising AOV (a stack's: its directional albedo at wi)."""
    if kind == DIFFUSE:
        return (p[0], p[1], p[2])
    if kind == CONDUCTOR:
        return conductor.albedo((p[0], p[1], p[2]), (p[3], p[4], p[5]), (p[6], p[7], p[8]))
    if kind == DIELECTRIC:
        return (p[1], p[2], p[3])
    if kind == COATED_DIFFUSE:
        return coated_diffuse.albedo(T, int(p[7]), p[1], (p[4], p[5], p[6]), wi[2])
    if kind == TABULATED:
        return tabulated.albedo(T, int(p[0]), (p[1], p[2], p[3]), wi[2])
    return (0.0, 0.0, 0.0)
