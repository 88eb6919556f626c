"""The stack table: every multi-interface layered material of a scene as kernel data, and
``bind_into``, which evaluates one stack at a lane's (u, v) into a flat float64 block.

``StackTable`` (one per scene; rows of the interface and medium arrays are grouped by stack):
  head      float64 (S, HEAD)  per stack: number of interfaces N, transmissive, the indices above
            and below the stack and of each slab, the estimator options, the first interface and
            medium rows (layout ``H_*``)
  textured  bool (S,)          some parameter of the stack has a texture: bind per lane;
            otherwise ``bound[s]`` (bound once at scene load) is the lane's block
  bound     float64 (S, BSIZE) the bound block of every untextured stack
  if_kind, if_dist, if_mask  int32 (I,);  if_values float64 (I, NSLOT), if_tex int32 (I, NSLOT):
            the interfaces' texturable parameters in the material table's slot layout
            (kernels/materials.py), written by each interface material's ``pack``; NULL rows hold
            their tint in the dielectric's tint slots
  if_nmode  int32 (I,) 0 no normal map, 1 a constant shading normal (``if_nval``, unit, its
            strength applied), 2 a normal-map texture (``if_nval`` its scale, ``if_ntex`` its id;
            RGB · 2 − 1; mixed by the strength in ``if_values[:, N_STRENGTH]``)
  if_bump   bool (I,) a bump map on top of it: height × distance and strength in the
            material slots B_HEIGHT / B_STRENGTH (kernels/bump.py), along the lane's dP/du, dP/dv
            in its shading frame (``duv``; the head's H_BUMP says a stack needs them)
  md_kind   int32 (M,) EMPTY / ABSORBING / SCATTERING (decided at load from constants)
  md_grey   bool (M,); md_values float64 (M, MSLOT), md_tex int32 (M, MSLOT): thickness,
            σt (1 or 3 slots: ``md_sigma3``), albedo, phase parameters (layout ``M_*``)
  md_phase  int32 (M,) phase kind (kernels/layered/phase.py); md_flags int32 (M,): bit 0 the
            orientation is a texture (decoded as value · 2 − 1), bit 1 SGGX flake preset,
            bit 2 an explicit SGGX matrix (``md_s6``)
  md_row    int32 (M,) the fiber-table row of a constant stddev (−1: interpolate per lane)
  FT        float64: the fiber σ table with one extra row per constant-stddev medium

A lane's bound block (``B``, BSIZE float64; ``table.bind_into`` or ``bound[s]``):
  [0, HEAD)                    the stack's head
  HEAD + l·iface.STRIDE        interface l (kernels/layered/iface.py layout)
  MED0 + k·MSTRIDE             medium k: kind, grey, τ0 = σt·thickness (RGB), albedo (RGB),
                               directional, then the phase block (phase.SIZE)
Nested stacks are flattened at load into the explicit stack (the same BSDF: Guo et al. §10);
the outer stack's estimator options apply, except that a flattened stack is evaluated with the
bidirectional estimator (``H_NESTED``): the paper nests stacks to use the unidirectional
estimator on several slabs, which on the explicit stack is heavy-tailed (single estimates ~10³ ×
the mean on the reference stack), while the explicit bidirectional estimator is what its
multi-layer figures use. At most ``MAX_INTERFACES`` = 16 interfaces.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .. import bump as _bump
from .. import materials as km
from ..bsdf import conductor, dielectric, diffuse
from ..jit import inlined, kernel
from ..params import param_rgb, param_scalar
from ..textures import lookup_gradient
from . import iface as ki
from . import phase as ph

MAX_INTERFACES = 16
EMPTY, ABSORBING, SCATTERING = 0, 1, 2
BI, UNI = 0, 1
APPROX, STOCHASTIC = 0, 1
LOBES = 4               # the closed-form reflection density (lobes.py); 2, 3: benchmark kinds

# head
H_N, H_TRANS, H_ETA_TOP, H_ETA_BOTTOM, H_ETA_SLAB = 0, 1, 2, 3, 4
H_EST, H_PDF, H_PDFC, H_MIS, H_MAXV, H_CHROM, H_IF0, H_MD0, H_NESTED = 20, 21, 22, 23, 24, 25, 26, 27, 28
H_BUMP = 29          # 1: an interface has a bump map (bind per lane, with the surface's dP/du, dP/dv)
HEAD = 32
# Without a surface (the BSDF inspector, tests), bump maps are read over UVs that run along the
# shading frame's x and y at one unit per metre: dP/du = x, dP/dv = y.
UNIT_DUV = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)
MED0 = HEAD + MAX_INTERFACES * ki.STRIDE
# medium block
M_KIND, M_GREY, M_TAU, M_ALB, M_DIR, M_PH = 0, 1, 2, 5, 8, 9
MSTRIDE = 32
BSIZE = MED0 + (MAX_INTERFACES - 1) * MSTRIDE
# medium slots (md_values / md_tex)
S_THICK, S_SIGMA, S_ALB, S_PA, S_PV = 0, 1, 4, 7, 8
MSLOT = 12
F_TEX_ORIENT, F_FLAKE, F_MATRIX, F_SLOT_A, F_SLOT_V = 1, 2, 4, 8, 16

StackTable = namedtuple("StackTable", [
    "head", "textured", "bound",
    "if_kind", "if_dist", "if_mask", "if_values", "if_tex", "if_nmode", "if_nval", "if_ntex", "if_bump",
    "md_kind", "md_grey", "md_sigma3", "md_values", "md_tex", "md_phase", "md_flags", "md_s6",
    "md_row", "FT"])


def if_offset(l: int) -> int:
    return HEAD + l * ki.STRIDE


def md_offset(k: int) -> int:
    return MED0 + k * MSTRIDE


# ----------------------------------------------------------------------------- per lane
# Texture lookups through two small non-inlined functions: bind_into evaluates ~20 parameters,
# and inlining a bilinear lookup at each of them made it the slowest kernel to compile (35 s).
@kernel
def _p3(TX, values, tex_id, u, v):
    return param_rgb(TX, values, tex_id, u, v)


@kernel
def _p1(TX, value, tex_id, u, v):
    return param_scalar(TX, value, tex_id, u, v)


@inlined
def _rgb(values, tex, r, slot, TX, u, v):
    return _p3(TX, (values[r, slot], values[r, slot + 1], values[r, slot + 2]), tex[r, slot], u, v)


@inlined
def _scalar(values, tex, r, slot, TX, u, v):
    return _p1(TX, values[r, slot], tex[r, slot], u, v)


@kernel
def _iface_params(values, tex, kind, r, TX, u, v):
    """The 12 lane parameters of interface row r (each kind's ``params``, kernels/bsdf/*.py)."""
    if kind == km.DIFFUSE:
        return diffuse.params(_rgb(values, tex, r, diffuse.COLOR, TX, u, v))
    if kind == km.CONDUCTOR:
        return conductor.params(_rgb(values, tex, r, conductor.ETA, TX, u, v),
                                _rgb(values, tex, r, conductor.K, TX, u, v),
                                _rgb(values, tex, r, conductor.TINT, TX, u, v),
                                _scalar(values, tex, r, conductor.AU, TX, u, v),
                                _scalar(values, tex, r, conductor.AV, TX, u, v))
    return dielectric.params(_scalar(values, tex, r, dielectric.ETA, TX, u, v),
                             _rgb(values, tex, r, dielectric.TINT, TX, u, v),
                             _scalar(values, tex, r, dielectric.AU, TX, u, v),
                             _scalar(values, tex, r, dielectric.AV, TX, u, v))


#: One interface as ``bind_iface`` reads it: its kind, microfacet distribution and masking, row
#: ``row`` of the slot arrays ``values``/``tex`` (constants, texture ids), and its normal: mode
#: (0 none, 1 constant ``nval``, 2 the normal-map texture ``ntex``) and whether it has a bump map.
IfaceRow = namedtuple("IfaceRow", ["kind", "dist", "mask", "values", "tex", "row", "nmode", "nval", "ntex",
                                   "bump"])


@kernel
def bind_iface(R, TX, u, v, duv, B, o):
    """Interface ``R`` (an IfaceRow) at (u, v) into B[o:o + iface.STRIDE]; ``duv`` the surface's
    dP/du, dP/dv in the lane's frame (for a bump map)."""
    kind, dist, mask, iv, it, r, mode, nval, ntex, bump = R
    B[o + ki.IF_KIND] = kind
    B[o + ki.IF_DIST] = dist
    B[o + ki.IF_MASK] = mask
    if kind == ki.NULL:
        t = _rgb(iv, it, r, km.D_TINT, TX, u, v)
        B[o + ki.IF_P] = t[0]
        B[o + ki.IF_P + 1] = t[1]
        B[o + ki.IF_P + 2] = t[2]
        B[o + ki.IF_DELTA] = 1.0
        B[o + ki.IF_TRANS] = 1.0
    else:
        p = _iface_params(iv, it, kind, r, TX, u, v)
        for j in range(12):
            B[o + ki.IF_P + j] = p[j]
        B[o + ki.IF_DELTA] = 1.0 if km.is_delta_only(kind, p) else 0.0
        B[o + ki.IF_TRANS] = 1.0 if kind == km.DIELECTRIC else 0.0
    B[o + ki.IF_FRAMED] = 0.0
    if mode > 0 or bump:
        n = (0.0, 0.0, 1.0)
        if mode == 1:
            n = nval
        elif mode == 2:
            t = _p3(TX, nval, ntex, u, v)
            n = _mixed(_above((2.0 * t[0] - 1.0, 2.0 * t[1] - 1.0, 2.0 * t[2] - 1.0)), iv[r, km.N_STRENGTH])
        if bump:
            gu, gv = _height_gradient(TX, it[r, km.B_HEIGHT], u, v)
            n = _above(_bump.tilt(n, (duv[0], duv[1], duv[2]), (duv[3], duv[4], duv[5]), gu, gv,
                                  iv[r, km.B_HEIGHT], iv[r, km.B_STRENGTH]))
        st = ki.frame_of_normal(n)
        B[o + ki.IF_FRAMED] = 1.0
        for j in range(3):
            B[o + ki.IF_N + j] = n[j]
            B[o + ki.IF_S + j] = st[0][j]
            B[o + ki.IF_T + j] = st[1][j]


@kernel
def _height_gradient(TX, t, u, v):
    return lookup_gradient(TX, t, u, v)


@kernel
def _above(n):
    """A unit normal kept above the surface (z ≥ 10⁻³), as the normal maps' (materials/normal.py)."""
    z = max(n[2], 1e-3)
    ln = np.sqrt(n[0] * n[0] + n[1] * n[1] + z * z)
    return (n[0] / ln, n[1] / ln, z / ln)


@kernel
def _mixed(n, k):
    """A normal map's normal mixed with the surface's (0, 0, 1) by the strength k, as Blender's
    Normal Map node: normalize(z + k (n − z))."""
    if k == 1.0:
        return n
    return _above((k * n[0], k * n[1], 1.0 + k * (n[2] - 1.0)))


@kernel
def bind_into(ST, TX, s, u, v, duv, B):
    """Evaluate stack ``s`` at (u, v) into the block B (see the module docstring); ``duv`` the
    surface's dP/du, dP/dv in the lane's frame (UNIT_DUV without a surface)."""
    for j in range(HEAD):
        B[j] = ST.head[s, j]
    N = int(ST.head[s, H_N])
    f0 = int(ST.head[s, H_IF0])
    m0 = int(ST.head[s, H_MD0])
    for l in range(N):
        r = f0 + l
        row = IfaceRow(ST.if_kind[r], ST.if_dist[r], ST.if_mask[r], ST.if_values, ST.if_tex, r, ST.if_nmode[r],
                       (ST.if_nval[r, 0], ST.if_nval[r, 1], ST.if_nval[r, 2]), ST.if_ntex[r], ST.if_bump[r])
        bind_iface(row, TX, u, v, duv, B, HEAD + l * ki.STRIDE)
    mv, mt = ST.md_values, ST.md_tex
    for k in range(N - 1):
        r = m0 + k
        o = MED0 + k * MSTRIDE
        B[o + M_KIND] = ST.md_kind[r]
        B[o + M_GREY] = 1.0 if ST.md_grey[r] else 0.0
        th = _scalar(mv, mt, r, S_THICK, TX, u, v)
        if ST.md_sigma3[r]:
            sg = _rgb(mv, mt, r, S_SIGMA, TX, u, v)
        else:
            x = _scalar(mv, mt, r, S_SIGMA, TX, u, v)
            sg = (x, x, x)
        alb = _rgb(mv, mt, r, S_ALB, TX, u, v)
        for j in range(3):
            B[o + M_TAU + j] = sg[j] * th
            B[o + M_ALB + j] = alb[j]
        pk = ST.md_phase[r]
        po = o + M_PH
        B[o + M_DIR] = 1.0 if ph.directional(pk) else 0.0
        flags = ST.md_flags[r]
        if flags & F_MATRIX:
            s6 = ST.md_s6
            ph.bind_sggx(B, po, (s6[r, 0], s6[r, 1], s6[r, 2], s6[r, 3], s6[r, 4], s6[r, 5]))
        else:
            # only the slots the kind has (F_SLOT_*): each read is a texture lookup's call
            a = _scalar(mv, mt, r, S_PA, TX, u, v) if flags & F_SLOT_A else 0.0
            ori = _rgb(mv, mt, r, S_PV, TX, u, v) if flags & F_SLOT_V else (0.0, 0.0, 1.0)
            if flags & F_TEX_ORIENT:
                ori = (2.0 * ori[0] - 1.0, 2.0 * ori[1] - 1.0, 2.0 * ori[2] - 1.0)
            ph.bind(B, po, pk, a, ori, 1 if flags & F_FLAKE else 0, ST.FT, ST.md_row[r])


@kernel
def bind_constant_rows(ST, TX):
    for s in range(ST.head.shape[0]):
        if not ST.textured[s]:
            bind_into(ST, TX, s, 0.0, 0.0, UNIT_DUV, ST.bound[s])


@kernel
def fill_rows(FT, rows, stddev):
    for i in range(rows.shape[0]):
        ph.fill_fiber_row(FT, rows[i], stddev[i])


# ----------------------------------------------------------------------------- assembly
def assemble(stacks, ifaces, media, FT, TX) -> StackTable:
    """The StackTable of the rows a builder collected (backend/layered/stack_table.py): per stack
    {"head", "textured"}, per interface {"row" (a kernels.materials.MaterialRow), "nmode",
    "nval", "ntex", "bump"}, per medium the dict of ``md_*`` values; ``FT`` the fiber table.
    Untextured stacks are bound once here."""
    S = max(len(stacks), 1)
    head = np.zeros((S, HEAD))
    textured = np.zeros(S, bool)
    for s, st in enumerate(stacks):
        head[s] = st["head"]
        textured[s] = st["textured"]
    I = max(len(ifaces), 1)
    if_kind = np.zeros(I, np.int32)
    if_dist = np.zeros(I, np.int32)
    if_mask = np.zeros(I, np.int32)
    if_values = np.zeros((I, km.NSLOT))
    if_tex = np.full((I, km.NSLOT), -1, np.int32)
    if_nmode = np.zeros(I, np.int32)
    if_nval = np.zeros((I, 3))
    if_ntex = np.full(I, -1, np.int32)
    if_bump = np.zeros(I, bool)
    for i, f in enumerate(ifaces):
        r = f["row"]
        if_kind[i], if_dist[i], if_mask[i] = r.kind, r.dist, r.masking
        if_values[i], if_tex[i] = r.values, r.tex
        if_nmode[i], if_nval[i], if_ntex[i], if_bump[i] = f["nmode"], f["nval"], f["ntex"], f["bump"]
    M = max(len(media), 1)
    md_kind = np.zeros(M, np.int32)
    md_grey = np.ones(M, bool)
    md_sigma3 = np.zeros(M, bool)
    md_values = np.zeros((M, MSLOT))
    md_tex = np.full((M, MSLOT), -1, np.int32)
    md_phase = np.zeros(M, np.int32)
    md_flags = np.zeros(M, np.int32)
    md_s6 = np.zeros((M, 6))
    md_row = np.full(M, -1, np.int32)
    for i, m in enumerate(media):
        md_kind[i], md_grey[i], md_sigma3[i] = m["kind"], m["grey"], m["sigma3"]
        md_values[i], md_tex[i] = m["values"], m["tex"]
        md_phase[i], md_flags[i], md_s6[i], md_row[i] = m["phase"], m["flags"], m["s6"], m["row"]
    ST = StackTable(head, textured, np.zeros((S, BSIZE)), if_kind, if_dist, if_mask, if_values,
                    if_tex, if_nmode, if_nval, if_ntex, if_bump, md_kind, md_grey, md_sigma3, md_values,
                    md_tex, md_phase, md_flags, md_s6, md_row, FT)
    if stacks:
        bind_constant_rows(ST, TX)
    return ST


def empty_table(TX=None) -> StackTable:
    """A table without stacks (every array one placeholder row): the types a render's table has."""
    from ..textures import empty_table as empty_textures
    return assemble([], [], [], np.zeros((1, 1)), TX if TX is not None else empty_textures())
