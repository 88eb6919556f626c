"""Counter-based random numbers: u = hash(seed, pixel, sample, dimension) in [0, 1).

No generator state is carried between lanes, bounces, work items or processes: the number a path
uses at a given dimension depends only on those four integers, so the same seed and sample count
give a bit-identical image for any worker count, batch size or adaptive round. The
low-discrepancy sampler (issue 17) replaces the hash by a scrambled sequence over the same keys.

Hash: three rounds of the SplitMix64 finaliser (Steele, Lea, Flood 2014), one per key, each key
multiplied by a distinct odd constant first. 53 random bits make a double in [0, 1).

Dimension plan of a path (``DIM_*``): the camera uses dimensions 0–3; bounce b uses
``BOUNCE_BASE + b·BOUNCE_DIMS + k`` for the fixed slots k below. Slots are read through the
path sampler (``sampler.py``: scrambled Sobol by default), which stratifies them in pairs:
(light selection, BSDF lobe), the light position and the BSDF direction are 2-D slots; Russian
roulette takes a hashed number (it gains nothing from stratification).
"""
from __future__ import annotations

import numpy as np

from .jit import kernel

DIM_FILTER = 0          # 2: pixel-filter offset
DIM_LENS = 2            # 2: aperture
BOUNCE_BASE = 4
BOUNCE_DIMS = 12
SLOT_LIGHT_PICK = 0     # 2-D slot, first: which light
SLOT_BSDF_LOBE = 1      #            second: lobe choice (reflect / refract)
SLOT_LIGHT = 2          # 2-D: point/direction on the light
SLOT_BSDF = 4           # 2-D: direction
SLOT_RR = 6             # 1 (hashed): Russian roulette
SLOT_SPARE = 7          # the layered walks' sub-stream (stream_key)
SLOT_MIX = 8            # 1 (hashed): which component of a Mix / Add Shader
SLOT_MIS_PDF = 9        # a layered continuation's deferred MIS pdf: its walks' sub-stream
SLOT_TIME = 10          # 2-D slot of bounce 0, first used: the camera ray's shutter time
# Next-event estimation of every light (2-4 lights): light k of a vertex reads the light slot at
# dim + k·DIM_NEXT_LIGHT, far beyond any bounce's dimensions (< 2^20 for up to 87 000 bounces).
DIM_NEXT_LIGHT = 1 << 20

_M0 = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xD1B54A32D192ED03)
_M2 = np.uint64(0xAEF17502108EF2D9)
_C0 = np.uint64(0xBF58476D1CE4E5B9)
_C1 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_INV53 = 1.0 / 9007199254740992.0


@kernel
def _mix(z):
    z = (z ^ (z >> _S30)) * _C0
    z = (z ^ (z >> _S27)) * _C1
    return z ^ (z >> _S31)


@kernel
def path_key(seed, pixel, sample):
    """The 64-bit key of one path (all of its dimensions hash from it)."""
    h = _mix(np.uint64(seed) * _M0 + np.uint64(pixel))
    return _mix(h ^ (np.uint64(sample) * _M1))


@kernel
def uniform(key, dim):
    """A double in [0, 1) for a path key and a dimension."""
    h = _mix(key ^ (np.uint64(dim) * _M2 + _M0))
    return np.float64(h >> _S11) * _INV53


@kernel
def stream_key(key, dim):
    """The key of a sub-stream of a path: ``uniform(stream_key(key, dim), k)`` for k = 0, 1, …
    (the layered walks of a bounce draw from ``dim = bounce_dim(b, SLOT_SPARE)``, as many numbers
    as their walks need)."""
    return _mix(key ^ (np.uint64(dim) * _M2 + _M0))


@kernel
def bounce_dim(bounce, slot):
    return BOUNCE_BASE + bounce * BOUNCE_DIMS + slot


@kernel
def fill_uniform(seed, pixels, samples, dim0, out):
    """Batch form (tests, the layered walk seeds): out[i, j] = uniform(key_i, dim0 + j)."""
    for i in range(out.shape[0]):
        key = path_key(seed, pixels[i], samples[i])
        for j in range(out.shape[1]):
            out[i, j] = uniform(key, dim0 + j)
