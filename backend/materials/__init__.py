"""Materials: one module per BSDF, all implementing ``base.BSDF`` over arrays.

``REGISTRY`` maps the scene-file ``type`` to a parser ``from_node(node) -> Material`` (``node`` is
a ``scene.reader.Node``; ``node.ctx`` is the load context). Modules register themselves with
``@register("type")`` when imported; ``load_all()`` imports every module of this folder but the
helpers, and ``ELSEWHERE``.
"""
from __future__ import annotations

import importlib
import pkgutil

REGISTRY: dict = {}

#: Modules of this package that hold no material type (the rest are found by ``load_all``: a new
#: BSDF is a new module here, nothing to list), and material types defined elsewhere.
HELPERS = ("base", "common", "fresnel", "metals", "microfacet", "normal", "row_bsdf", "specfun")
ELSEWHERE = ("backend.layered.material",)


def modules() -> list[str]:
    """The material-type modules: this folder's (but the helpers) and ELSEWHERE."""
    here = [f"{__name__}.{m.name}" for m in pkgutil.iter_modules(__path__)
            if not m.ispkg and m.name not in HELPERS]
    return here + list(ELSEWHERE)


def register(type_name: str):
    def deco(parser):
        REGISTRY[type_name] = parser
        return parser
    return deco


_LOADED: list = []


def load_all() -> dict:
    # Once per process: every material a scene parses asks, and listing the folder each time
    # (pkgutil) was 3 ms of a 60 ms start-up for a scene of 12 materials.
    if not _LOADED:
        for name in modules():
            importlib.import_module(name)
        _LOADED.append(True)
    return REGISTRY
