"""Materials: one module per BSDF, all implementing ``base.BSDF`` over arrays.

``REGISTRY`` maps the scene-file ``type`` to a parser ``from_node(node) -> Material`` (``node`` is
a ``scene.reader.Node``; ``node.ctx`` is the load context). Modules register themselves with
``@register("type")`` when imported; ``load_all()`` imports the known modules.
"""
from __future__ import annotations

import importlib

REGISTRY: dict = {}

MODULES = (
    "backend.materials.diffuse",
    "backend.materials.conductor",
    "backend.materials.dielectric",
    "backend.materials.emission",
    "backend.materials.mix",
    "backend.layered.material",
)


def register(type_name: str):
    def deco(parser):
        REGISTRY[type_name] = parser
        return parser
    return deco


def load_all() -> dict:
    for name in MODULES:
        try:
            importlib.import_module(name)
        except ModuleNotFoundError as exc:  # a module not written yet
            if exc.name != name:
                raise
    return REGISTRY
