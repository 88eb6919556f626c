"""Mixtures of materials: Blender's Mix Shader and Add Shader.

``{"type": "mix", "factor": f, "materials": [A, B]}`` is (1 − f)·A + f·B (``factor`` *tex*, in
[0, 1]); ``{"type": "add", "materials": [A, B, ...]}`` is A + B + … (2 to ``MAX_ADD`` of them;
it may reflect more light than it receives, as in Cycles). Components are material objects
(any type, mixes included, up to ``MAX_DEPTH`` levels) or preset names; they may not emit.

Rendering (kernels/integrator.py ``_resolve_mix``): at each hit the lane picks one component —
A with probability 1 − f, B with f; for ``add`` each with probability 1/n and weight n — and
shades the hit with it alone (light sample, MIS, continuation), so every BSDF keeps its own
sampling and the estimate's expectation is the mixture. The loader appends the components to
the scene's material list (``flatten``); the mix's row holds their indices.
"""
from __future__ import annotations

from . import register
from .base import Material

MAX_ADD = 8        # components of one Add Shader (the material table's slots)
MAX_DEPTH = 4      # mixes of mixes: the kernel resolves at most this many levels


class MixMaterial(Material):
    two_sided = True

    def __init__(self, kind: str, components: list, factor=None):
        self.type_name = kind                    # "mix" or "add"
        self.components = components             # Material objects
        self.factor = factor                     # mix: a scalar Param
        self.indices: list[int] = []             # their rows in the material table (flatten)

    def pack(self, row) -> None:
        from ..kernels import materials as km
        row.kind = km.MIX if self.type_name == "mix" else km.ADD
        if self.factor is not None:
            row.set(km.MIX_FACTOR, self.factor, 1)
        row.values[km.MIX_N] = len(self.indices)
        for k, index in enumerate(self.indices):
            row.values[km.MIX_C0 + k] = index

    @property
    def uses_textures(self) -> bool:
        return bool(getattr(self.factor, "is_constant", True) is False) or any(
            c.uses_textures for c in self.components)


def _components(node, lo: int, hi: int) -> list:
    from ..scene.loader import parse_material
    lst = node.child("materials")
    items = lst.items()
    if not lo <= len(items) <= hi:
        raise lst.fail(f"expected {lo if lo == hi else f'{lo} to {hi}'} materials, got {len(items)}")
    out = []
    for item in items:
        material = parse_material(item)
        if getattr(material, "emission", None) is not None:
            raise item.fail("a component of a mix cannot emit light (not supported yet): put the "
                            "emission on a material of its own")
        if _depth(material) >= MAX_DEPTH:
            raise item.fail(f"mixes nest at most {MAX_DEPTH} levels deep")
        out.append(material)
    return out


def _depth(material) -> int:
    if not isinstance(material, MixMaterial):
        return 0
    return 1 + max(_depth(c) for c in material.components)


@register("mix")
def parse_mix(node) -> MixMaterial:
    factor = node.param("factor", 0.5, channels=1, lo=0.0, hi=1.0, color=False)
    return MixMaterial("mix", _components(node, 2, 2), factor)


@register("add")
def parse_add(node) -> MixMaterial:
    return MixMaterial("add", _components(node, 2, MAX_ADD))


def flatten(materials: list, names: list) -> None:
    """Append every mix's components to the scene's material list (in place) and record their
    indices on the mix; nested mixes are flattened too."""
    i = 0
    while i < len(materials):
        material = materials[i]
        if isinstance(material, MixMaterial) and not material.indices:
            for k, component in enumerate(material.components):
                material.indices.append(len(materials))
                materials.append(component)
                names.append(f"{names[i]}#{k}")
        i += 1
