"""Lights: one module per light type, all implementing ``base.Light``.

``REGISTRY`` maps the scene-file light ``type`` to a parser ``from_node(node, ctx) -> Light``.
"""
from __future__ import annotations

REGISTRY: dict = {}


def register(type_name: str):
    def deco(parser):
        REGISTRY[type_name] = parser
        return parser
    return deco
