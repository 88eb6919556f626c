"""3-vectors as Numba tuples (x, y, z): they live in registers, so per-lane code allocates nothing.

Directions follow the renderer's conventions (unit length where a docstring says so; local
shading frame z = shading normal, x = tangent). float64 throughout.
"""
from __future__ import annotations

import math

from .jit import kernel


@kernel
def v3(x, y, z):
    return (float(x), float(y), float(z))


@kernel
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@kernel
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@kernel
def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@kernel
def mul3(a, b):
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@kernel
def madd(a, s, b):
    """a + s·b"""
    return (a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2])


@kernel
def neg(a):
    return (-a[0], -a[1], -a[2])


@kernel
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@kernel
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@kernel
def length(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@kernel
def normalize(a):
    """a/|a|; the zero vector stays zero."""
    n = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    if n > 0.0:
        inv = 1.0 / n
        return (a[0] * inv, a[1] * inv, a[2] * inv)
    return a


@kernel
def max3(a):
    return max(a[0], max(a[1], a[2]))


@kernel
def is_zero(a):
    return a[0] == 0.0 and a[1] == 0.0 and a[2] == 0.0


@kernel
def luminance(a):
    """Rec.709 luminance of linear RGB."""
    return 0.2126 * a[0] + 0.7152 * a[1] + 0.0722 * a[2]


@kernel
def coordinate_system(n):
    """Two unit vectors orthogonal to unit n (Duff et al. 2017, branchless form)."""
    sign = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    s = (1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    t = (b, sign + n[1] * n[1] * a, -n[1])
    return s, t


@kernel
def shading_frame(n, tangent):
    """(s, t) completing unit n to the shading frame: the tangent Gram-Schmidt'ed against n;
    Duff et al.'s frame (coordinate_system's s) where the tangent is undefined (a mesh without
    UVs has a zero tangent). Divides by |s| rather than multiplying by its inverse: the bounce
    loop's images are defined by this rounding (kernels/integrator.py)."""
    d = dot(tangent, n)
    s = (tangent[0] - d * n[0], tangent[1] - d * n[1], tangent[2] - d * n[2])
    ls = math.sqrt(dot(s, s))
    if ls > 1e-8:
        s = (s[0] / ls, s[1] / ls, s[2] / ls)
    else:
        sign = 1.0 if n[2] >= 0.0 else -1.0
        a = -1.0 / (sign + n[2])
        s = (1.0 + sign * n[0] * n[0] * a, sign * (n[0] * n[1] * a), -sign * n[0])
    return s, cross(n, s)


@kernel
def to_local(s, t, n, v):
    return (dot(v, s), dot(v, t), dot(v, n))


@kernel
def to_world(s, t, n, v):
    return (v[0] * s[0] + v[1] * t[0] + v[2] * n[0],
            v[0] * s[1] + v[1] * t[1] + v[2] * n[1],
            v[0] * s[2] + v[1] * t[2] + v[2] * n[2])


@kernel
def safe_div(a, b):
    """a/b, 0 where b == 0."""
    return a / b if b != 0.0 else 0.0
