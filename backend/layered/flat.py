"""A layered stack with its nested stacks flattened into one explicit stack (Guo et al. §10:
nesting and the explicit stack are the same BSDF; the paper's multi-layer figures use the
explicit one)."""
from __future__ import annotations


class Flat:
    """A stack with its nested stacks flattened (``flatten``)."""

    def __init__(self, interfaces, normals, media, eta_slab, eta_top, eta_bottom, transmissive,
                 nested):
        self.interfaces, self.normals, self.media = interfaces, normals, media
        self.eta_slab, self.eta_top, self.eta_bottom = eta_slab, eta_top, eta_bottom
        self.transmissive = transmissive
        self.nested = nested        # a nested stack was flattened into it


def flatten(material) -> Flat:
    """The explicit stack of a material whose interfaces may be nested stacks: a nested stack's
    interfaces and media replace it. The outer options apply."""
    ifaces, normals, media, etas = [], [], [], []
    nested = False
    for i, (m, nrm) in enumerate(zip(material.interfaces, material.normals)):
        if getattr(m, "type_name", None) == "layered":
            nested = True
            inner = flatten(m)
            ifaces += inner.interfaces
            normals += inner.normals
            media += inner.media
            etas += inner.eta_slab
        else:
            ifaces.append(m)
            normals.append(nrm)
        if i < len(material.media):
            media.append(material.media[i])
            etas.append(material.eta_slab[i])
    return Flat(ifaces, normals, media, etas, material.eta_top, material.eta_bottom, material.transmissive,
                nested)
