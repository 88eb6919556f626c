"""IES (LM-63) intensity per lane: Cycles' interpolation of the candela table.

Frame (docs/lights.md, IES lights; Cycles ``svm_node_ies``): for a direction d in the light's local frame,
vertical angle v = acos(−d_z) (0 = local −Z) and horizontal angle h = atan2(d_x, d_y) + π, so
h = 0 → local −Y, 90° → −X, 180° → +Y, 270° → +X (clockwise seen from above, i.e. from +Z).

Interpolation (Cycles ``kernel_ies_interp``): find the table cell (h_i, v_i) containing the angles,
take the fractions linearly in angle within the cell, then Catmull-Rom (uniform, in *index* space)
vertically in the four columns h_i−1..h_i+2 and horizontally across the four results. Missing
neighbours: vertically, below the first row use row 1 when the table starts at the pole (v = 0),
else repeat row v_i; past the last row use row nv−2 when the table ends at v = 180°, else repeat
row v_i+1. Horizontally, a table covering 0..360° wraps (skipping the duplicate 360° column); a
partial one (types A/B) repeats column h_i on *both* sides (Cycles does exactly this). The result
is clamped at 0. Intensity is 0 for v ≥ the last vertical angle, v < the first one, and h outside
the table. One deliberate difference: h is wrapped to [0°, 360°), so the direction exactly along
local −Y gets the 0° value where Cycles' float atan2 can return h = 360° and hence 0.

Table block (float64, at ``off``): [h angles (nh) | v angles (nv) | candela (nh × nv, row i = the
column at h_i)], angles in radians, strictly increasing. ``flags``: WRAP_H | WRAP_VLOW |
WRAP_VHIGH (built by ``backend/ies/profile.py``). Units: candela.
"""
from __future__ import annotations

import math

from ..discrete import lower_bound
from ..jit import kernel

WRAP_H = 1        # the table covers 0..360°
WRAP_VLOW = 2     # it starts at the pole v = 0
WRAP_VHIGH = 4    # it ends at the pole v = 180°
from ..consts import TWO_PI


@kernel
def catmull_rom(a, b, c, d, x):
    """Uniform Catmull-Rom spline between b (x = 0) and c (x = 1); a, d are the outer neighbours."""
    return 0.5 * (((d + 3.0 * (b - c) - a) * x + (2.0 * a - 5.0 * b + 4.0 * c - d)) * x + (c - a)) * x + b


@kernel
def directions_to_angles(d):
    """(h, v) in radians for a local direction d (need not be unit; zero → v = π/2)."""
    n = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    z = -d[2] / (n if n > 0.0 else 1.0)
    v = math.acos(min(max(z, -1.0), 1.0))
    h = math.atan2(d[0], d[1]) + math.pi
    if h >= TWO_PI:
        h -= TWO_PI
    return h, v


@kernel
def _column(a, t, nv, col, ra, r0, r1, rd, x):
    base = t + col * nv
    return catmull_rom(a[base + ra], a[base + r0], a[base + r1], a[base + rd], x)


@kernel
def intensity_angles(a, off, nh, nv, flags, h, v):
    """Candela at horizontal/vertical angles (radians, h in [0, 2π))."""
    H = off
    V = off + nh
    T = off + nh + nv
    if not (v >= a[V] and v < a[V + nv - 1] and h >= a[H] and h < a[H + nh - 1]):
        return 0.0
    # Cell lookup as Cycles' linear scan: the first i with angle[i + 1] >= x.
    hi = lower_bound(a, H, H + nh, h) - H - 1
    hi = min(max(hi, 0), nh - 2)
    vi = lower_bound(a, V, V + nv, v) - V - 1
    vi = min(max(vi, 0), nv - 2)
    hf = (h - a[H + hi]) / (a[H + hi + 1] - a[H + hi])   # angles strictly increase
    vf = (v - a[V + vi]) / (a[V + vi + 1] - a[V + vi])
    # Neighbour rows (vertical) and columns (horizontal); see the module docstring.
    if vi > 0:
        ra = vi - 1
    else:
        ra = 1 if flags & WRAP_VLOW else vi
    if vi + 2 < nv:
        rd = vi + 2
    else:
        rd = nv - 2 if flags & WRAP_VHIGH else vi + 1
    if hi > 0:
        ca = hi - 1
    else:
        ca = nh - 2 if flags & WRAP_H else hi
    if hi + 2 < nh:
        cd = hi + 2
    else:
        cd = 1 if flags & WRAP_H else hi
    c0 = _column(a, T, nv, ca, ra, vi, vi + 1, rd, vf)
    c1 = _column(a, T, nv, hi, ra, vi, vi + 1, rd, vf)
    c2 = _column(a, T, nv, hi + 1, ra, vi, vi + 1, rd, vf)
    c3 = _column(a, T, nv, cd, ra, vi, vi + 1, rd, vf)
    # Catmull-Rom overshoots below zero near dark regions.
    return max(catmull_rom(c0, c1, c2, c3, hf), 0.0)


@kernel
def intensity(a, off, nh, nv, flags, d):
    """Candela along a direction d in the light's local frame (from the light outwards)."""
    if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > 0.0:
        h, v = directions_to_angles(d)
        return intensity_angles(a, off, nh, nv, flags, h, v)
    return 0.0
