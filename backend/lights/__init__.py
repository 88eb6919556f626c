"""Lights: one module per light type, all implementing ``base.Light``.

``REGISTRY`` maps the scene-file light ``type`` to a parser ``from_node(node) -> Light``;
``WORLD_REGISTRY`` maps the ``world.type`` to a parser returning an infinite Light (or None).
Modules register themselves when imported; ``load_all()`` imports the known modules.
"""
from __future__ import annotations

import importlib

REGISTRY: dict = {}
WORLD_REGISTRY: dict = {}

MODULES = (
    "backend.lights.point",
    "backend.lights.spot",
    "backend.lights.sun",
    "backend.lights.area",
    "backend.lights.environment",
    "backend.lights.mesh",
)


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
    for name in MODULES:
        try:
            importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
    return REGISTRY, WORLD_REGISTRY
