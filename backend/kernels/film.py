"""Adding a work item's samples to the film, one sample at a time in sample-index order.

Each pixel's sums are accumulated sample by sample (sample 0, 1, 2, … of that pixel), never as
partial sums of a work item added together: floating-point addition is not associative, and
this order is the only one that does not depend on how samples were grouped into work items,
rounds (adaptive or not), batches or workers. So the same seed and sample count give a
bit-identical image however the work was cut. A non-finite sample (NaN/Inf in any channel) is
dropped (it adds 0 and is counted).
"""
from __future__ import annotations

import math

from .jit import kernel


@kernel(nogil=True)
def accumulate(f_sum, f_sq, f_alb, f_nrm, f_alpha, f_count, f_first, f_pass, pixels, spp, L, albedo,
               normal, alpha, aux):
    """Lane i is sample i % spp of pixels[i // spp] (lanes of a pixel adjacent, in sample order).
    Data passes (``aux``, backend/passes.py): its first ``f_first.shape[1]`` columns are kept
    from the pixel's sample 0 (the first sample ever added to it), the others summed into
    ``f_pass``; no columns when no pass was asked for. Returns the number of non-finite samples
    dropped."""
    nf = f_first.shape[1]
    ns = f_pass.shape[1]
    bad = 0
    # Nested over pixels and samples: a 64-bit integer division per lane (i // spp) cost more
    # than the additions.
    for q in range(L.shape[0] // spp):
        pix = pixels[q]
        for i in range(q * spp, (q + 1) * spp):
            x, y, z = L[i, 0], L[i, 1], L[i, 2]
            if math.isfinite(x) and math.isfinite(y) and math.isfinite(z):
                f_sum[pix, 0] += x
                f_sum[pix, 1] += y
                f_sum[pix, 2] += z
                f_sq[pix, 0] += x * x
                f_sq[pix, 1] += y * y
                f_sq[pix, 2] += z * z
            else:
                bad += 1
            for c in range(3):
                f_alb[pix, c] += albedo[i, c]
                f_nrm[pix, c] += normal[i, c]
            if f_count[pix] == 0:
                for c in range(nf):
                    f_first[pix, c] = aux[i, c]
            for c in range(ns):
                f_pass[pix, c] += aux[i, nf + c]
            f_alpha[pix] += alpha[i]
            f_count[pix] += 1
    return bad


@kernel(nogil=True)
def add_splats(f_caustic, pix, rgb):
    """A work item's caustic splats (kernels/caustics.py) added in the order the item wrote
    them. On the master's thread, so compiled: np.add.at took 0.12 s for the demo's 3 M splats
    of one render, serial time a 16-core render cannot spread."""
    for k in range(pix.shape[0]):
        q = pix[k]
        f_caustic[q, 0] += rgb[k, 0]
        f_caustic[q, 1] += rgb[k, 1]
        f_caustic[q, 2] += rgb[k, 2]
