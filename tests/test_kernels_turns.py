"""cos and sin of angles in turns (kernels/turns.py) against an extended-precision reference."""
import numpy as np
from numba import njit

from backend.kernels.turns import cos_sin_turns


@njit(cache=False)
def _batch(u, c, s):
    for i in range(u.size):
        c[i], s[i] = cos_sin_turns(u[i])


def test_cos_sin_turns_within_two_ulp_of_one_everywhere():
    rng = np.random.default_rng(3)
    # Random turns, a fine grid, the octant and quadrant boundaries and their neighbours, the
    # end of [0, 1), negative and large arguments (reduced exactly).
    edges = np.arange(-8, 17) / 8.0
    u = np.concatenate([rng.random(400_000), np.linspace(0.0, 1.0, 20_001), edges,
                        np.nextafter(edges, -np.inf), np.nextafter(edges, np.inf),
                        [1.0 - 2.0 ** -53, 2.0 ** -40, -0.3, 12345.678]])
    c = np.empty_like(u)
    s = np.empty_like(u)
    _batch(u, c, s)
    two_pi = 4 * np.arccos(np.longdouble(0))           # 2π to 64 bits
    frac = u.astype(np.longdouble) - np.floor(u.astype(np.longdouble))
    ref_c = np.cos(two_pi * frac)
    ref_s = np.sin(two_pi * frac)
    err = max(np.abs(c - ref_c).max(), np.abs(s - ref_s).max())
    assert float(err) <= 2 * 2.0 ** -52, float(err)
    # Exact at the quadrant points, and cos² + sin² = 1 to rounding.
    q = np.array([0.0, 0.25, 0.5, 0.75])
    cq = np.empty(4)
    sq = np.empty(4)
    _batch(q, cq, sq)
    assert np.array_equal(cq, [1.0, 0.0, -1.0, 0.0]) and np.array_equal(np.abs(sq), [0.0, 1.0, 0.0, 1.0])
    assert np.abs(c * c + s * s - 1.0).max() < 4e-16
