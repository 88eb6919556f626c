"""The ``layered`` material: schema parsing, the IOR chain, estimator options, binding.

Schema (docs/materials.md, "layered")::

    {"type": "layered",
     "interfaces": [<interface>, ...],       # 0 = top; N >= 1
     "media": [<medium>, ...],               # exactly N − 1 (slab i between interfaces i, i+1)
     "estimator": "auto" | "bi" | "uni", "pdf": "lobes" | "approx" | "stochastic",
     "pdf_constant": 0.1, "max_vertices": 1024, "mis": true, "emission": ...}

Interfaces: ``dielectric``, ``conductor``, ``diffuse`` (the standard materials' schema),
``null`` (index-matched pass-through) and a nested ``layered``. IOR chain: each dielectric's
``ior`` is the index *below* it; the index above an interface is the index below the one above
it (1 above the top), injected as the dielectric's ``ior_above`` / the conductor's ``eta_above``
(so a metal's Fresnel is relative to the coating it sits under). Estimator options not given in
the material come from the scene's ``render.layered`` object (``ctx.cache["layered_defaults"]``),
then from the defaults in ``bsdf.Options``.
"""
from __future__ import annotations

import numpy as np

from ..materials import REGISTRY, register
from ..materials.base import Material, ShadingContext
from ..materials.normal import parse_detail
from ..scene.reader import Node, _describe
from .bsdf import LayeredBSDF, Options, new_stats
from .medium import parse_medium
from .stack import NullMaterial

INTERFACE_TYPES = ("dielectric", "conductor", "diffuse", "null", "layered")
OPTION_KEYS = ("estimator", "pdf", "pdf_constant", "max_vertices", "mis")


def parse_options(node: Node, defaults: Node | None) -> Options:
    """Per-material estimator options over the scene-level defaults."""
    base = Options()
    values = {}
    for src in (defaults, node):
        if src is None:
            continue
        if src.has("estimator"):
            values["estimator"] = src.string("estimator", choices=("auto", "bi", "uni"))
        if src.has("pdf"):
            values["pdf"] = src.string("pdf", choices=("lobes", "approx", "stochastic"))
        if src.has("pdf_constant"):
            values["pdf_constant"] = src.number("pdf_constant", lo=0.0)
        if src.has("max_vertices"):
            values["max_vertices"] = src.integer("max_vertices", lo=2, hi=1 << 20)
        if src.has("mis"):
            values["mis"] = src.boolean("mis")
        src.ignore(*OPTION_KEYS)
    opts = Options(**{**base.__dict__, **values})
    if not opts.mis and opts.estimator != "uni":
        # The bidirectional estimator is defined by its MIS weights over all connection
        # strategies; "without MIS" has a meaning only for the unidirectional one.
        raise node.fail('"mis": false needs "estimator": "uni" (the bidirectional estimator '
                        'always combines its connection strategies with MIS)', "mis")
    return opts


class LayeredMaterial(Material):
    type_name = "layered"

    def __init__(self, interfaces: list, media: list, eta_slab: list[float], eta_bottom: float,
                 options: Options, emission=None, eta_top: float = 1.0, normals: list | None = None):
        self.interfaces = interfaces        # Materials (bind → BSDF)
        self.normals = normals or [None] * len(interfaces)  # per interface: None or a SurfaceDetail
        self.media = media                  # MediumSpecs
        self.eta_slab = eta_slab
        self.eta_bottom = eta_bottom
        self.eta_top = eta_top              # index above the stack (≠ 1 when nested)
        self.options = options
        self.emission = emission
        self.transmissive = _transmits(interfaces[-1])
        self.two_sided = not self.transmissive
        self.stats = new_stats()

    @property
    def uses_textures(self) -> bool:
        return any(getattr(m, "uses_textures", False) for m in self.interfaces) or \
            any(m.uses_textures for m in self.media) or \
            any(nm is not None and not nm.is_constant for nm in self.normals)

    @property
    def closed_form(self) -> dict | None:
        """The parameters of the deterministic form that evaluates this stack
        (layered/coated_diffuse.py), or None: the random walk (also whenever the material asks
        for a walk estimator by name)."""
        if self.options.estimator != "auto":
            return None
        if not hasattr(self, "_closed_form"):
            from .coated_diffuse import qualifies
            from .flat import flatten
            self._closed_form = qualifies(flatten(self))
        return self._closed_form

    @property
    def table_block(self):
        """The table of a uniform stack solved by adding-doubling (layered/tabulated.py), built
        once; None: no table (a closed form, the walk by request, or a stack it does not cover)."""
        if self.options.estimator != "auto" or self.closed_form is not None:
            return None
        if not hasattr(self, "_table_block"):
            from .tabulated import build
            self._table_block = build(self)
        return self._table_block

    def pack(self, row) -> None:
        from ..kernels import materials as km
        if len(self.interfaces) == 1 and self.normals[0] is None:
            self.interfaces[0].pack(row)   # a one-interface stack is that interface's BSDF
            return
        form = self.closed_form
        if form is not None:
            _pack_coated_diffuse(row, form)
            return
        block = self.table_block
        if block is not None:
            row.kind = km.TABULATED
            row.values[km.TB_TAB] = row.tables.add(block)
            from .flat import flatten
            body = flatten(self).interfaces[-1]
            if getattr(body, "type_name", "") == "diffuse":
                row.set(km.TB_RHO, body.color, 3)       # read only by a textured body's table
            return
        row.kind = km.LAYERED
        if getattr(row, "stacks", None) is None:
            raise RuntimeError("a layered material needs a stack table (build_material_table(stacks=...))")
        row.values[km.LAYER_ID] = row.stacks.add(self)

    def kernel_table(self):
        """(StackTable, TextureTable, stack id) of this material alone, for ``LayeredBSDF`` (built
        once; the renderer builds one table for the whole scene instead)."""
        if getattr(self, "_kernel_table", None) is None:
            from ..kernels.params import ParamPacker
            from .stack_table import StackBuilder
            packer = ParamPacker()
            builder = StackBuilder(packer)
            sid = builder.add(self)
            tx = packer.table()
            self._kernel_table = (builder.table(tx), tx, sid)
        return self._kernel_table

    def bind(self, ctx: ShadingContext):
        if len(self.interfaces) == 1:
            # A one-interface stack is that interface's analytic BSDF.
            return self.interfaces[0].bind(ctx)
        if self.closed_form is not None or self.table_block is not None:
            from ..materials.row_bsdf import RowBSDF
            return RowBSDF(self, ctx.uv if self.uses_textures else np.zeros((1, 2)), ctx.n)
        uv = ctx.uv if self.uses_textures else np.zeros((1, 2))
        return LayeredBSDF(self, uv, ctx.n, self.stats)


def _pack_coated_diffuse(row, form: dict) -> None:
    """A dielectric over a Lambertian body in closed form (kernels/bsdf/coated_diffuse.py)."""
    from ..kernels import materials as km
    from .coated_diffuse import table
    rough = form["roughness"]
    alpha = None if not rough.is_constant else float(np.asarray(rough.mean()).reshape(-1)[0])
    block = table(form["eta"], form["tint"], alpha, form["dist"], form["masking"], form["tau"])
    row.kind = km.COATED_DIFFUSE
    row.values[km.CD_ETA] = form["eta"]
    row.set(km.CD_AU, rough, 1)
    row.set(km.CD_AV, rough, 1)
    row.set(km.CD_RHO, form["color"], 3)
    row.values[km.CD_TAB] = row.tables.add(block)
    row.microfacet(form["dist"], form["masking"])


def _transmits(material) -> bool:
    if isinstance(material, (NullMaterial, LayeredMaterial)):
        return True if isinstance(material, NullMaterial) else material.transmissive
    return material.type_name == "dielectric"


def _constant_ior(material, inode: Node) -> float:
    p = material.ior
    if not p.is_constant:
        raise inode.fail("inside a layered stack the index of refraction must be a number "
                         "(it is the index of the whole slab below)", "ior")
    return float(np.asarray(p.bind(None)).reshape(-1)[0])


# An interface's own normal and bump maps (materials/normal.parse_detail).
DETAIL_KEYS = ("normal", "normal_strength", "bump")


def parse_interface(inode: Node, eta_above: float):
    """One interface; returns (material, index below it, its SurfaceDetail or None)."""
    inode.require_object()
    kind = inode.value.get("type")
    if kind not in INTERFACE_TYPES:
        raise inode.fail(f"expected one of {', '.join(map(repr, INTERFACE_TYPES))}, got {_describe(kind)}", "type")
    if kind == "null":
        inode.string("type")
        detail = parse_detail(inode)
        inode.finish()
        return NullMaterial(), eta_above, detail
    if kind == "layered":
        for key in DETAIL_KEYS:
            if inode.has(key):
                raise inode.fail("a nested stack takes normal and bump maps on its own interfaces", key)
        inode.string("type")
        nested = parse_layered(inode, eta_above)
        return nested, (nested.eta_bottom if nested.transmissive else eta_above), None
    detail = parse_detail(inode)
    implied = {"dielectric": "ior_above", "conductor": "eta_above"}.get(kind)
    value = {k: v for k, v in inode.value.items() if k not in DETAIL_KEYS}
    if implied is not None:
        if implied in value:
            raise inode.fail("implied by the stack (the index below the interface above); "
                             "remove it", implied)
        value[implied] = eta_above
    sub = Node(value, inode.path, inode.ctx)
    sub.string("type")
    material = REGISTRY[kind](sub)
    sub.finish()
    if getattr(material, "emission", None) is not None:
        raise inode.fail("an interface of a layered stack cannot emit; put \"emission\" on the "
                         "layered material", "emission")
    if kind == "dielectric":
        return material, _constant_ior(material, inode), detail
    return material, eta_above, detail


def parse_layered(node: Node, eta_above: float = 1.0) -> LayeredMaterial:
    """A layered material; nested stacks count against limits.MAX_LAYER_NESTING (their cost
    grows with the nesting) and all interfaces against limits.MAX_STACK_INTERFACES."""
    from ..limits import MAX_LAYER_NESTING, MAX_STACK_INTERFACES
    cache = node.ctx.cache
    depth = cache.get("layered_nesting", 0) + 1
    if depth > MAX_LAYER_NESTING:
        raise node.fail(f"layered materials nested {depth} deep; at most {MAX_LAYER_NESTING} "
                        f"levels (a stack inside a stack inside a stack) are supported")
    cache["layered_nesting"] = depth
    try:
        material = _parse_layered(node, eta_above)
    finally:
        cache["layered_nesting"] = depth - 1
    count = _interface_count(material)
    if count > MAX_STACK_INTERFACES:
        raise node.fail(f"{count} interfaces (nested stacks included); at most "
                        f"{MAX_STACK_INTERFACES} are supported", "interfaces")
    return material


def _interface_count(material) -> int:
    if not isinstance(material, LayeredMaterial):
        return 1
    return sum(_interface_count(m) for m in material.interfaces)


def _parse_layered(node: Node, eta_above: float) -> LayeredMaterial:
    from ..materials import load_all
    load_all()
    node.require_object()
    inodes = node.child("interfaces").items()
    if not inodes:
        raise node.fail("a layered material needs at least one interface", "interfaces")
    from ..limits import MAX_STACK_INTERFACES
    if len(inodes) > MAX_STACK_INTERFACES:
        raise node.fail(f"{len(inodes)} interfaces; at most {MAX_STACK_INTERFACES} are supported",
                        "interfaces")
    interfaces, etas, normals = [], [], []
    eta = eta_above
    for i, inode in enumerate(inodes):
        material, eta, normal = parse_interface(inode, eta)
        interfaces.append(material)
        etas.append(eta)
        normals.append(normal)
        if i < len(inodes) - 1 and not _transmits(material):
            raise inode.fail(f"interface {i} is opaque ({inode.value.get('type')}): nothing reaches "
                             f"the layers below it; it must be the last interface")
    n_media = len(inodes) - 1
    mnode = node.optional_child("media")
    mnodes = mnode.items() if mnode is not None else []
    if len(mnodes) != n_media:
        raise node.fail(f"expected {n_media} media (one between each pair of interfaces), "
                        f"got {len(mnodes)}", "media")
    media = [parse_medium(m) for m in mnodes]
    defaults_value = node.ctx.cache.get("layered_defaults")
    defaults = Node(defaults_value, "render.layered", node.ctx) if defaults_value else None
    options = parse_options(node, defaults)
    if defaults is not None:
        defaults.finish()
    from ..materials.emission import parse_emission
    emission = parse_emission(node)
    node.finish()
    eta_slab = etas[:-1] if n_media else []
    if len(interfaces) == 1 and normals[0] is not None:
        key = next(k for k in DETAIL_KEYS if inodes[0].has(k))
        raise inodes[0].fail("a one-interface stack is that interface's BSDF: put the normal or "
                             "bump map on the material instead of its interface", key)
    if len(interfaces) == 1 and getattr(interfaces[0], "type_name", "") == "null":
        # A lone null interface has no surface and no medium: nothing for light to meet. (Null
        # interfaces belong between media, where they bound a slab.)
        raise inodes[0].fail("a stack whose only interface is 'null' has no surface; give it a "
                             "surface interface, or a medium between two interfaces", "type")
    return LayeredMaterial(interfaces, media, list(eta_slab), etas[-1], options, emission, eta_above,
                           normals)


@register("layered")
def parse(node: Node) -> LayeredMaterial:
    return parse_layered(node, 1.0)


# Exposed for tests and tools.
__all__ = ["LayeredMaterial", "parse_layered", "parse", "Options"]
