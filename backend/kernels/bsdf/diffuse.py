"""Lambertian reflection, f = colour/π, cosine-weighted sampling. Two-sided: wi below the
surface is handled by mirroring both directions (the integrator already turns the frame towards
the viewer; this keeps the BSDF usable from either side inside layered stacks)."""
from __future__ import annotations

from ..consts import INV_PI
from ..jit import inlined, kernel
from ..warp import cosine_hemisphere


@kernel
def eval_pdf(color, wi, wo):
    if wi[2] * wo[2] > 0.0:
        c = abs(wo[2]) * INV_PI
        return (color[0] * c, color[1] * c, color[2] * c), c
    return (0.0, 0.0, 0.0), 0.0


@kernel
def sample(color, wi, u0, u1):
    wo = cosine_hemisphere(u0, u1)
    if wi[2] < 0.0:
        wo = (wo[0], wo[1], -wo[2])
    if wi[2] == 0.0 or wo[2] == 0.0:
        return wo, (0.0, 0.0, 0.0), 0.0, False
    return wo, color, INV_PI * abs(wo[2]), False


# ----------------------------------------------------------------------------- binding
# The kind's slots in a material row (kernels/materials.py ``MaterialTable.values``: its Python
# material packs them) and its lane parameters: the 12-tuple every kind binds to (one Numba type
# for all, kernels/materials.py ``bind``), written and read here only.
COLOR = 3                    # RGB albedo


@inlined
def params(color):
    return (color[0], color[1], color[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@inlined
def eval_pdf_p(p, wi, wo):
    return eval_pdf((p[0], p[1], p[2]), wi, wo)


@inlined
def sample_p(p, wi, u0, u1):
    return sample((p[0], p[1], p[2]), wi, u0, u1)


@inlined
def albedo_p(p):
    return (p[0], p[1], p[2])
