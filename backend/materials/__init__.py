"""Materials: one module per BSDF, all implementing ``base.BSDF`` over arrays.

``REGISTRY`` maps the scene-file ``type`` to a parser ``from_node(node, ctx) -> Material``.
"""
from __future__ import annotations

REGISTRY: dict = {}


def register(type_name: str):
    def deco(parser):
        REGISTRY[type_name] = parser
        return parser
    return deco
