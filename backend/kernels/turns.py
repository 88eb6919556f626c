"""cos and sin of an angle given in turns (θ = 2π·u), per lane, without calling libm.

Samplers draw azimuths as 2π·u (cosine hemispheres, visible microfacet normals, phase functions,
the fiber microflake's rejection loop). glibc's sin and cos took 4–5 % of a render of the
two-microflake-slab sphere and 3 % of the Cornell box (perf); this costs about a third.

Reduction in turns is exact: x = 4u (a power of two), k = the nearest integer to x and
r = x − k ∈ [−½, ½] are exact in float64 for |u| < 2^50, so θ = k·π/2 + a with a = r·π/2 ∈
[−π/4, π/4] (one rounding). On that interval the Taylor series of sin a to a^17 and of cos a to
a^18 are complete to < 1e-19 (the next terms: a^19/19! ≤ 9e-20, a^20/20! ≤ 4e-21), so the result
is within a few ulp of the rounded true values (tests/test_kernels_turns.py measures it); the
quadrant k mod 4 then only swaps and negates (exact)."""
from __future__ import annotations

import math

from .jit import kernel

HALF_PI = 0.5 * math.pi
# 1/n! with alternating signs: sin a = a(1 + a²(S3 + a²(S5 + …))), cos a = 1 + a²(C2 + a²(C4 + …)).
S3, S5, S7, S9 = -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0
S11, S13, S15, S17 = -1.0 / 39916800.0, 1.0 / 6227020800.0, -1.0 / 1307674368000.0, 1.0 / 355687428096000.0
C2, C4, C6, C8 = -0.5, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0
C10, C12, C14, C16 = -1.0 / 3628800.0, 1.0 / 479001600.0, -1.0 / 87178291200.0, 1.0 / 20922789888000.0
C18 = -1.0 / 6402373705728000.0


@kernel
def cos_sin_turns(u):
    """(cos 2πu, sin 2πu)."""
    x = 4.0 * u
    k = math.floor(x + 0.5)
    a = (x - k) * HALF_PI
    z = a * a
    s = S15 + z * S17
    s = S13 + z * s
    s = S11 + z * s
    s = S9 + z * s
    s = S7 + z * s
    s = S5 + z * s
    s = S3 + z * s
    s = a + a * z * s
    c = C16 + z * C18
    c = C14 + z * c
    c = C12 + z * c
    c = C10 + z * c
    c = C8 + z * c
    c = C6 + z * c
    c = C4 + z * c
    c = C2 + z * c
    c = 1.0 + z * c
    q = int(k) & 3
    if q == 0:
        return c, s
    if q == 1:
        return -s, c
    if q == 2:
        return -c, -s
    return s, -c
