"""Collects a scene's layered materials into the kernels' stack table (kernels/layered/table.py:
layout, per-lane binding): each stack flattened (nested stacks become one explicit stack), its
interfaces packed into material-table rows, its media into medium rows, and the fiber table
extended by one row per constant-stddev microflake medium."""
from __future__ import annotations

import numpy as np

from ..errors import SceneError
from ..kernels import materials as km
from ..kernels.layered import iface as ki
from ..kernels.layered import phase as ph
from ..kernels.layered.table import (ABSORBING, APPROX, BI, EMPTY, F_FLAKE, F_MATRIX, F_SLOT_A, F_SLOT_V,
                                     F_TEX_ORIENT, H_BUMP, H_CHROM, H_EST, H_ETA_BOTTOM, H_ETA_SLAB, H_ETA_TOP,
                                     H_IF0, H_MAXV, H_MD0, H_MIS, H_N, H_NESTED, H_PDF, H_PDFC, H_TRANS, HEAD, LOBES,
                                     MAX_INTERFACES, MSLOT, S_ALB, S_PA, S_PV, S_SIGMA, S_THICK, SCATTERING,
                                     STOCHASTIC, UNI, StackTable, assemble, fill_rows)
from ..materials.dielectric import DielectricMaterial
from .flat import flatten
from .phase_schema import BY_NAME
from .phase.fiber import kernel_table
from .stack import NullMaterial


class StackBuilder:
    """Collects the layered materials of a scene (``LayeredMaterial.pack`` calls ``add``) and
    builds the ``StackTable`` once the scene's textures are known (``table``)."""

    def __init__(self, packer):
        self.packer = packer
        self.stacks: list[dict] = []
        self.ifaces: list = []
        self.media: list = []
        self.fiber_rows: list[float] = []
        self._ids: dict = {}

    def add(self, material) -> int:
        key = id(material)
        if key in self._ids:
            return self._ids[key]
        flat = flatten(material)
        if len(flat.interfaces) > MAX_INTERFACES:
            # The loader checks limits.MAX_STACK_INTERFACES (the same number) with the field's
            # path; this guards a material built in code.
            raise SceneError("", "interfaces", f"a layered stack has {len(flat.interfaces)} "
                             f"interfaces (nested stacks flattened); at most {MAX_INTERFACES} are "
                             f"supported")
        opts = material.options
        sid = len(self.stacks)
        head = np.zeros(HEAD)
        N = len(flat.interfaces)
        head[H_N] = N
        head[H_TRANS] = 1.0 if flat.transmissive else 0.0
        head[H_ETA_TOP] = flat.eta_top
        head[H_ETA_BOTTOM] = flat.eta_bottom
        head[H_ETA_SLAB:H_ETA_SLAB + len(flat.eta_slab)] = flat.eta_slab
        head[H_EST] = UNI if opts.estimator == "uni" else BI
        head[H_PDF] = {"approx": APPROX, "stochastic": STOCHASTIC, "lobes": LOBES}[opts.pdf]
        head[H_PDFC] = opts.pdf_constant
        head[H_MIS] = 1.0 if opts.mis else 0.0
        head[H_MAXV] = opts.max_vertices
        head[H_NESTED] = 1.0 if flat.nested else 0.0
        head[H_IF0] = len(self.ifaces)
        head[H_MD0] = len(self.media)
        textured = False
        for m, detail in zip(flat.interfaces, flat.normals):
            row, tex = self._interface(m, detail)
            self.ifaces.append(row)
            textured |= tex
            head[H_BUMP] = 1.0 if (row["bump"] or head[H_BUMP]) else 0.0
        chromatic = False
        for spec in flat.media:
            row, tex = self._medium(spec)
            self.media.append(row)
            textured |= tex
            chromatic |= (not row["grey"]) and row["kind"] == SCATTERING
        head[H_CHROM] = 1.0 if chromatic else 0.0
        self.stacks.append({"head": head, "textured": textured})
        self._ids[key] = sid
        return sid

    def _interface(self, material, detail):
        row = km.MaterialRow(self.packer)
        textured = bool(getattr(material, "uses_textures", False))
        if isinstance(material, NullMaterial):
            row.kind = ki.NULL
            row.set(km.D_TINT, [1.0, 1.0, 1.0], 3)
        else:
            material.pack(row)
            if isinstance(material, DielectricMaterial) and material.ior.is_constant and \
                    float(np.asarray(material.ior.bind(None)).reshape(-1)[0]) / material.ior_above == 1.0:
                # Equal indices on both sides: every microfacet refracts straight through, a
                # delta transmission (the microfacet BTDF's half vector degenerates to 0/0).
                row.kind = ki.NULL
        out = {"row": row, "nmode": 0, "nval": np.zeros(3), "ntex": -1, "bump": False}
        if detail is None:
            return out, textured
        normal = detail.normal
        if normal is not None:
            row.values[km.N_STRENGTH] = detail.strength
            if normal.texture:
                values, tex = self.packer.pack(normal.param, 3)
                out.update(nmode=2, nval=values, ntex=tex)
                textured = True
            else:
                n = np.asarray(normal.param.bind(None), dtype=np.float64).reshape(3).copy()
                n[2] = max(n[2], 1e-3)
                n /= np.linalg.norm(n)
                k = detail.strength                 # Blender's Normal Map Strength, as _mixed
                n = np.array([k * n[0], k * n[1], 1.0 + k * (n[2] - 1.0)])
                n[2] = max(n[2], 1e-3)
                n /= np.linalg.norm(n)
                if not np.allclose(n, [0.0, 0.0, 1.0], atol=1e-12):
                    out.update(nmode=1, nval=n)
        bump = detail.bump
        if bump is not None:
            row.set(km.B_HEIGHT, bump.height, 1, bump.distance)
            row.values[km.B_STRENGTH] = bump.strength
            out["bump"] = True
            textured = True
        return out, textured

    def _medium(self, spec):
        values = np.zeros(MSLOT)
        tex = np.full(MSLOT, -1, np.int32)

        def put(slot, param, channels):
            v, t = self.packer.pack(param, channels)
            values[slot:slot + channels] = v
            tex[slot] = t

        sigma3 = spec.sigma_t.channels == 3
        put(S_THICK, spec.thickness, 1)
        put(S_SIGMA, spec.sigma_t, 3 if sigma3 else 1)
        put(S_ALB, spec.albedo, 3)
        kind = SCATTERING
        if spec.is_empty:
            kind = EMPTY
        elif spec.albedo.is_constant and not np.any(spec.albedo.bind(None)):
            kind = ABSORBING
        p = spec.phase
        pk = ph.KINDS[p.type_name]
        flags = 0
        s6 = np.zeros(6)
        row = -1
        params = p.params
        for param in BY_NAME[p.type_name].params:           # the schema's slots (phase_schema.py)
            if param.key not in params:
                continue
            if param.slot == "a":
                put(S_PA, params[param.key], 1)
                flags |= F_SLOT_A
            elif param.slot == "v":
                put(S_PV, params[param.key], 3)
                flags |= F_SLOT_V
                if not params[param.key].is_constant:
                    flags |= F_TEX_ORIENT                      # decoded like a normal map
        # Two kinds' own extras: the fiber's σ row for a constant spread, SGGX's matrix or shape.
        if pk == ph.FIBER and params["stddev"].is_constant:
            row = ph.FIRST_MEDIUM_ROW + len(self.fiber_rows)
            self.fiber_rows.append(float(np.asarray(params["stddev"].bind(None)).reshape(-1)[0]))
        if "matrix" in p.settings:
            flags |= F_MATRIX
            s6 = np.asarray(p.settings["matrix"], dtype=np.float64).reshape(6)
        elif p.settings.get("shape") == "flake":
            flags |= F_FLAKE
        textured = bool(spec.uses_textures)
        return {"kind": kind, "grey": bool(spec.grey), "sigma3": sigma3, "values": values, "tex": tex,
                "phase": pk, "flags": flags, "s6": s6, "row": row}, textured

    def table(self, TX) -> StackTable:
        if self.stacks:
            base = kernel_table()
        else:
            base = np.zeros((1, 1))     # no layered stack: the walks never read the fiber table
        FT = np.zeros((base.shape[0] + len(self.fiber_rows), base.shape[1]))
        FT[:base.shape[0]] = base
        if self.fiber_rows:
            fill_rows(FT, np.arange(ph.FIRST_MEDIUM_ROW, ph.FIRST_MEDIUM_ROW + len(self.fiber_rows)),
                      np.array(self.fiber_rows))
        return assemble(self.stacks, self.ifaces, self.media, FT, TX)
