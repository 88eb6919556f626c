"""The path sampler: which number in [0, 1) a path uses at each of its dimensions.

Two samplers over the same keys (seed, pixel, sample index, dimension), so the same seed and
sample count give a bit-identical image however the work is cut (scene ``render.sampler``):

* ``"sobol"`` (default): Owen-scrambled Sobol points, padded per dimension slot, after Burley
  2020 ("Practical Hash-based Owen Scrambling", JCGT 9(4)). Every slot — 2-D for the pixel
  filter, the lens, a light position and a BSDF direction, 1-D for light selection, the lobe
  choice and Russian roulette — takes the first one or two Sobol dimensions, whose 2-D
  projection is a (0, 2)-sequence: any power-of-two prefix of a pixel's samples is stratified in
  every elementary interval. Slots are decorrelated from each other and from other pixels by
  shuffling the sample index (a nested uniform scramble of its bits, a random permutation that
  keeps power-of-two prefixes whole) and by Owen-scrambling each coordinate, both seeded by a
  hash of (seed, pixel, slot). The error of a pixel falls faster than 1/√N where the integrand
  is smooth, and never slower than with independent numbers.
* ``"independent"``: the counter-based hash of ``rng.py`` (the reference; also what the layered
  walks use for their inner dimensions, whose count is not fixed, and what bounces beyond the
  integrator's ``STRATIFIED_BOUNCES`` use: measured, stratifying them gains nothing visible).

Arithmetic is 32-bit (masks on 64-bit integers, since Numba promotes mixed integer types).
"""
from __future__ import annotations

import numpy as np

from .jit import kernel
from .rng import path_key, uniform

SOBOL = 0
INDEPENDENT = 1
SAMPLERS = {"sobol": SOBOL, "independent": INDEPENDENT}

_M32 = np.uint64(0xFFFFFFFF)
_INV32 = 1.0 / 4294967296.0


@kernel
def _reverse32(x):
    x = ((x >> np.uint64(1)) & np.uint64(0x55555555)) | ((x & np.uint64(0x55555555)) << np.uint64(1))
    x = ((x >> np.uint64(2)) & np.uint64(0x33333333)) | ((x & np.uint64(0x33333333)) << np.uint64(2))
    x = ((x >> np.uint64(4)) & np.uint64(0x0F0F0F0F)) | ((x & np.uint64(0x0F0F0F0F)) << np.uint64(4))
    x = ((x >> np.uint64(8)) & np.uint64(0x00FF00FF)) | ((x & np.uint64(0x00FF00FF)) << np.uint64(8))
    x = ((x >> np.uint64(16)) & np.uint64(0x0000FFFF)) | ((x & np.uint64(0x0000FFFF)) << np.uint64(16))
    return x & _M32


@kernel
def _lk_permute(x, seed):
    """Burley's improved Laine–Karras hash: bijective on 32 bits, each output bit depends only
    on the input bits at and below it (so, on reversed bits, a nested uniform scramble)."""
    x = (x + seed) & _M32
    x = (x ^ (x * np.uint64(0x6C50B47C))) & _M32
    x = (x ^ (x * np.uint64(0xB82F1E52))) & _M32
    x = (x ^ (x * np.uint64(0xC7AFE638))) & _M32
    x = (x ^ (x * np.uint64(0x8D22F6E6))) & _M32
    return x


@kernel
def owen_scramble(x, seed):
    """Nested uniform (Owen) scramble of a 32-bit fixed-point number."""
    return _reverse32(_lk_permute(_reverse32(x), seed))


@kernel
def _mix32(x):
    """A 32-bit integer hash (Wellons' "lowbias32" constants): well-mixed scramble seeds."""
    x = x & _M32
    x ^= x >> np.uint64(16)
    x = (x * np.uint64(0x7FEB352D)) & _M32
    x ^= x >> np.uint64(15)
    x = (x * np.uint64(0x846CA68B)) & _M32
    x ^= x >> np.uint64(16)
    return x


@kernel
def pixel_seed(seed, pixel):
    """Per-pixel scramble seed (computed once per lane; every slot derives its own from it)."""
    return _mix32(np.uint64(pixel) ^ _mix32(np.uint64(seed) ^ (np.uint64(seed) >> np.uint64(32))))


def _sobol1_bytes() -> np.ndarray:
    """Sobol dimension 1 (polynomial x + 1: direction numbers v_{k+1} = v_k ^ (v_k >> 1) from
    2^31, the Pascal matrix mod 2), tabulated per index byte: T[b, x] = XOR of the direction
    numbers of the bits set in byte value x at byte position b. The shuffled index is a full
    32-bit number, so this replaces a 32-step bit loop by four lookups (a 8 KiB table)."""
    v = [0x80000000]
    for _ in range(31):
        v.append(v[-1] ^ (v[-1] >> 1))
    t = np.zeros((4, 256), np.uint64)
    for b in range(4):
        for x in range(256):
            r = 0
            for bit in range(8):
                if (x >> bit) & 1:
                    r ^= v[8 * b + bit]
            t[b, x] = r
    return t


SOBOL1_BYTES = _sobol1_bytes()


@kernel
def _sobol1_gen(i):
    """Sobol dimension 1 of a 32-bit index (see ``_sobol1_bytes``)."""
    return (SOBOL1_BYTES[0, i & np.uint64(0xFF)] ^ SOBOL1_BYTES[1, (i >> np.uint64(8)) & np.uint64(0xFF)]
            ^ SOBOL1_BYTES[2, (i >> np.uint64(16)) & np.uint64(0xFF)]
            ^ SOBOL1_BYTES[3, (i >> np.uint64(24)) & np.uint64(0xFF)])


@kernel
def _shuffled(pseed, sample, dim):
    """(slot seed, the sample index permuted by a nested uniform scramble of its bits)."""
    s = _mix32(pseed ^ (np.uint64(dim) * np.uint64(0x9E3779B9)))
    return s, owen_scramble(np.uint64(sample) & _M32, s)


@kernel
def sobol1(pseed, sample, dim):
    s, i = _shuffled(pseed, sample, dim)
    # Dimension 0 is van der Corput, reverse(i); Owen-scrambled: reverse(LK(i)).
    return np.float64(_reverse32(_lk_permute(i, _mix32(s + np.uint64(1))))) * _INV32


@kernel
def sobol2(pseed, sample, dim):
    s, i = _shuffled(pseed, sample, dim)
    x = _reverse32(_lk_permute(i, _mix32(s + np.uint64(1))))
    y = owen_scramble(_sobol1_gen(i), _mix32(s + np.uint64(2)))
    return np.float64(x) * _INV32, np.float64(y) * _INV32


@kernel
def get1(kind, pseed, key, sample, dim):
    """The number of a 1-D slot starting at ``dim`` (``pseed`` = pixel_seed(seed, pixel),
    ``key`` = rng.path_key(seed, pixel, sample))."""
    if kind == INDEPENDENT:
        return uniform(key, dim)
    return sobol1(pseed, sample, dim)


@kernel
def get2(kind, pseed, key, sample, dim):
    """The two numbers of a 2-D slot starting at ``dim``."""
    if kind == INDEPENDENT:
        return uniform(key, dim), uniform(key, dim + 1)
    return sobol2(pseed, sample, dim)


@kernel
def fill(kind, seed, pixels, samples, dim, two, out):
    """Batch form (tests): out[i] = the slot's number(s) for (pixels[i], samples[i])."""
    for i in range(out.shape[0]):
        key = path_key(seed, pixels[i], samples[i])
        ps = pixel_seed(seed, pixels[i])
        if two:
            out[i, 0], out[i, 1] = get2(kind, ps, key, samples[i], dim)
        else:
            out[i, 0] = get1(kind, ps, key, samples[i], dim)
