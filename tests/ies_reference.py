"""An independent, deliberately plain reference for IES tests (scalar loops, no shared code).

Written from Cycles' description (docs/lights.md, IES lights, and Cycles' kernel_ies_interp), differently from
backend/ies: the full-circle table is built by *folding* each target angle back into the file's
data (inverse mapping) rather than by mirroring arrays; directions are turned into angles with
atan2(−x, −y); the kernel is a scalar loop per query. It only takes the raw file numbers
(angles and candela table as written) from the parser, whose raw output is checked separately
against the README table.
"""
from __future__ import annotations

import math

import numpy as np


def _index_of(angles, a):
    for i, x in enumerate(angles):
        if abs(x - a) < 1e-6:
            return i
    raise KeyError(f"angle {a} not in {list(angles)}")


def reference_grid(ptype: int, Hf, Vf, table, factor):
    """(h_deg list, v_deg list, value(i_h, i_v)) in the Cycles frame, built by inverse mapping.

    Hf, Vf: the file's horizontal and vertical angles; table[iH][iV] as written.
    """
    Hf = [float(x) for x in Hf]
    Vf = [float(x) for x in Vf]
    T = [[float(x) * factor for x in row] for row in table]
    if ptype == 1:  # type C
        v_out = list(Vf)
        if len(Hf) == 1:
            h_out = [0.0, 360.0]
            return h_out, v_out, (lambda ih, iv: T[0][iv])
        off = 90.0 if abs(Hf[0] - 90.0) < 1e-4 else 0.0
        rel = [x - off for x in Hf]
        span = rel[-1]
        if abs(span - 90.0) < 1e-4:
            h_out = sorted(set([round(a, 9) for r in rel for a in (r, 180 - r, 180 + r, 360 - r)]))

            def fold(h):
                h = min(h, 360.0 - h)
                return min(h, 180.0 - h)
        elif abs(span - 180.0) < 1e-4:
            h_out = sorted(set([round(a, 9) for r in rel for a in (r, 360 - r)]))

            def fold(h):
                return min(h, 360.0 - h)
        elif abs(span - 360.0) < 1e-4:
            h_out = list(rel)

            def fold(h):
                return h
        else:  # 360° column missing: it equals the 0° column
            h_out = list(rel) + [360.0]

            def fold(h):
                return 0.0 if abs(h - 360.0) < 1e-6 else h
        return h_out, v_out, (lambda ih, iv: T[_index_of(rel, fold(h_out[ih]))][iv])

    if ptype == 2:  # type B: h = file V + 90, v = file H + 90 (halves given from 0 are mirrored)
        v_half = abs(Vf[0]) < 1e-4
        h_half = abs(Hf[0]) < 1e-4
        h_out = sorted(set([x + 90 for x in Vf] + ([90 - x for x in Vf] if v_half else [])))
        v_out = sorted(set([x + 90 for x in Hf] + ([90 - x for x in Hf] if h_half else [])))

        def value(ih, iv):
            V = h_out[ih] - 90.0
            H = v_out[iv] - 90.0
            if v_half:
                V = abs(V)
            if h_half:
                H = abs(H)
            return T[_index_of(Hf, H)][_index_of(Vf, V)]
        return h_out, v_out, value

    # type A: h = 180 − H (a 0..90 half also at 180 + H), v = V + 90
    h_half = abs(Hf[0]) < 1e-4
    h_out = sorted(set([180 - x for x in Hf] + ([180 + x for x in Hf] if h_half else [])))
    v_out = [x + 90 for x in Vf]

    def value(ih, iv):
        H = 180.0 - h_out[ih]
        if h_half:
            H = abs(H)
        return T[_index_of(Hf, H)][iv]
    return h_out, v_out, value


class ReferenceProfile:
    def __init__(self, lm63file):
        f = lm63file
        h, v, value = reference_grid(f.photometric_type, f.horizontal_angles, f.vertical_angles,
                                     f.candela, f.multiplier * f.ballast_factor * f.ballast_lamp_factor)
        self.h = [math.radians(x) for x in h]
        self.v = [math.radians(x) for x in v]
        self.T = [[value(i, j) for j in range(len(v))] for i in range(len(h))]

    @staticmethod
    def cubic(a, b, c, d, x):
        # Catmull-Rom written in Hermite form (tangents (c − a)/2, (d − b)/2).
        m0, m1 = 0.5 * (c - a), 0.5 * (d - b)
        x2, x3 = x * x, x * x * x
        return ((2 * x3 - 3 * x2 + 1) * b + (x3 - 2 * x2 + x) * m0
                + (-2 * x3 + 3 * x2) * c + (x3 - x2) * m1)

    def at_angles(self, h, v):
        H, V, T = self.h, self.v, self.T
        nh, nv = len(H), len(V)
        if v < V[0] or v >= V[-1] or h < H[0] or h >= H[-1]:
            return 0.0
        wrap_h = H[0] < 1e-7 and H[-1] > 2 * math.pi - 1e-7
        wrap_lo = V[0] < 1e-7
        wrap_hi = V[-1] > math.pi - 1e-7
        i = 0
        while H[i + 1] < h:
            i += 1
        j = 0
        while V[j + 1] < v:
            j += 1
        fh = (h - H[i]) / (H[i + 1] - H[i])
        fv = (v - V[j]) / (V[j + 1] - V[j])

        def column(k):
            col = T[k]
            b, c = col[j], col[j + 1]
            a = col[j - 1] if j > 0 else (col[1] if wrap_lo else b)
            d = col[j + 2] if j + 2 < nv else (col[nv - 2] if wrap_hi else c)
            return self.cubic(a, b, c, d, fv)

        b, c = column(i), column(i + 1)
        a = column(i - 1) if i > 0 else (column(nh - 2) if wrap_h else b)
        d = column(i + 2) if i + 2 < nh else (column(1) if wrap_h else b)
        return max(self.cubic(a, b, c, d, fh), 0.0)

    def at_direction(self, d):
        x, y, z = (float(c) for c in d)
        n = math.sqrt(x * x + y * y + z * z)
        v = math.acos(max(-1.0, min(1.0, -z / n)))
        h = math.atan2(-x, -y) % (2 * math.pi)  # 0 at −Y, 90° at −X (clockwise from above)
        return self.at_angles(h, v)

    def bilinear_flux(self):
        """∫∫ I sin v dv dh with I bilinear in each cell, integrated exactly per cell [lm]."""
        H, V, T = self.h, self.v, self.T
        total = 0.0
        for i in range(len(H) - 1):
            dh = H[i + 1] - H[i]
            for j in range(len(V) - 1):
                v0, v1 = V[j], V[j + 1]
                # I averaged over h is linear in v: a + s (v − v0)
                a = 0.5 * (T[i][j] + T[i + 1][j])
                b = 0.5 * (T[i][j + 1] + T[i + 1][j + 1])
                s = (b - a) / (v1 - v0)
                int_sin = math.cos(v0) - math.cos(v1)
                int_lin = -(v1 - v0) * math.cos(v1) + math.sin(v1) - math.sin(v0)
                total += dh * (a * int_sin + s * int_lin)
        return total


def rotation_matrix(axis, angle_deg):
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    a = math.radians(angle_deg)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * (K @ K)


def parse_readme_table(path):
    """Rows of the README index as dicts keyed by the header names."""
    rows = []
    header = None
    for line in open(path, encoding="utf-8"):
        if not line.startswith("|"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if header is None:
            header = cells
            continue
        if set(cells[0]) <= set("-: "):
            continue
        rows.append(dict(zip(header, cells)))
    return rows
