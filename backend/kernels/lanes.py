"""Per-lane access to the arrays of the array entry points (``*batch.py``: loops over lanes for
NumPy callers): a parameter given once for every lane or once per lane, and rows of (n, 3)
directions and colours."""
from __future__ import annotations

from .jit import inlined


@inlined
def at(a, i):
    """Lane i's value of a (1,) or (n,) array: one value for every lane, or one per lane."""
    return a[i if a.shape[0] > 1 else 0]


@inlined
def rgb_at(a, i):
    """Lane i's row of a (1, 3) or (n, 3) array, as a 3-tuple."""
    j = i if a.shape[0] > 1 else 0
    return (a[j, 0], a[j, 1], a[j, 2])


@inlined
def row3(a, i):
    """Row i of an (n, 3) array, as a 3-tuple."""
    return (a[i, 0], a[i, 1], a[i, 2])


@inlined
def set_row3(a, i, v):
    a[i, 0] = v[0]
    a[i, 1] = v[1]
    a[i, 2] = v[2]
