"""Lights: one module per light type, all implementing ``base.Light``.

``REGISTRY`` maps the scene-file light ``type`` to a parser ``from_node(node) -> Light``;
``WORLD_REGISTRY`` maps the ``world.type`` to a parser returning an infinite Light (or None).
Modules register themselves when imported; ``load_all()`` imports every module of this folder
but the helpers.
"""
from __future__ import annotations

import importlib
import pkgutil

REGISTRY: dict = {}
WORLD_REGISTRY: dict = {}

#: The modules of this package that hold no light type (the rest are found by ``load_all``: a new
#: light type is a new module here, nothing to list).
HELPERS = ("base", "common", "profiles", "selection")


def modules() -> list[str]:
    """The light-type modules of this package, found in its folder."""
    return [f"{__name__}.{m.name}" for m in pkgutil.iter_modules(__path__)
            if not m.ispkg and m.name not in HELPERS]


def register(type_name: str):
    def deco(parser):
        REGISTRY[type_name] = parser
        return parser
    return deco


def register_world(type_name: str):
    def deco(parser):
        WORLD_REGISTRY[type_name] = parser
        return parser
    return deco


def load_all() -> tuple[dict, dict]:
    for name in modules():
        importlib.import_module(name)
    return REGISTRY, WORLD_REGISTRY
