"""A material's Lamina layer stack (``Material.lamina``) → material JSON (docs/materials.md).

N interfaces with N−1 media give ``{"type": "layered", "interfaces": [...], "media": [...]}``;
a stack of one interface is written as that interface's own material type.
"""
from __future__ import annotations

from ...backend.layered.phase_schema import BY_ENUM
from ..util import f32, rgb


class StackError(Exception):
    """A stack that cannot be exported (empty, or a nested material cycle)."""


def alpha(r: float) -> float:
    """Blender perceptual roughness → microfacet α (as Cycles: α = r²)."""
    return f32(float(r) * float(r))


def _source(layer, image) -> str:
    return f"interface '{layer.name}' (image '{image.name}')"


def _labelled(images, tex, text: str):
    """``tex``, remembered by the exporter as coming from ``text`` (names.py); stand-ins for the
    exporter (preset fingerprints) need not keep labels."""
    label = getattr(images, "label", None)
    return label(tex, text) if label is not None else tex


def _scalar(value: float, image, images, *, squared: bool = False, layer=None):
    if image is not None and images is not None:
        tex = images.texture(image, scale=value, squared=squared)
        if tex is not None:
            return _labelled(images, tex, _source(layer, image)) if layer is not None else tex
    return value


def _colour(value, image, images, layer=None):
    if image is not None and images is not None:
        tex = images.texture(image, scale=rgb(value))
        if tex is not None:
            return _labelled(images, tex, _source(layer, image)) if layer is not None else tex
    return rgb(value)


def _microfacet(layer, images) -> dict:
    out = {"roughness": _scalar(alpha(layer.roughness), layer.roughness_texture, images,
                                squared=not layer.roughness_texture_alpha, layer=layer)}
    if layer.use_anisotropy:
        out["roughness_v"] = alpha(layer.roughness_v)
    out["distribution"] = layer.distribution.lower()
    if layer.masking == "SEPARABLE":
        out["masking"] = "separable"
    return out


def _detail(layer, images) -> dict:
    """The interface's normal and bump maps ("normal", "normal_strength", "bump"; the same keys
    as a whole material's, so a one-interface stack, written as its interface, keeps them)."""
    out = {}
    if images is None:
        return out
    if layer.normal_texture is not None and layer.normal_strength > 0.0:
        tex = images.texture(layer.normal_texture)
        if tex is not None:
            out["normal"] = _labelled(images, tex, _source(layer, layer.normal_texture))
            if layer.normal_strength != 1.0:
                out["normal_strength"] = f32(layer.normal_strength)
    if layer.bump_texture is not None and layer.bump_distance != 0.0 and layer.bump_strength > 0.0:
        tex = images.texture(layer.bump_texture)
        if tex is not None:
            bump = {"height": _labelled(images, tex, _source(layer, layer.bump_texture)),
                    "distance": f32(layer.bump_distance), "strength": f32(layer.bump_strength)}
            if layer.bump_invert:
                bump["invert"] = True
            out["bump"] = bump
    return out


def interface_json(layer, images, visiting: tuple, linked=None) -> dict:
    kind = layer.kind
    if kind == "MATERIAL":
        nested = layer.material
        if nested is None:
            raise StackError(f"interface '{layer.name or 'Nested'}' has no material set")
        return stack_json(nested, images, visiting, linked=linked)
    return {**_interface_json(layer, images), **_detail(layer, images)}


def _interface_json(layer, images) -> dict:
    kind = layer.kind
    if kind == "DIELECTRIC":
        return {"type": "dielectric", "ior": f32(layer.ior), **_microfacet(layer, images)}
    if kind == "CONDUCTOR":
        out = {"type": "conductor"}
        if layer.metal == "CUSTOM":
            out["eta"] = rgb(layer.eta)
            out["k"] = rgb(layer.k)
        else:
            out["metal"] = layer.metal
        out.update(_microfacet(layer, images))
        if any(abs(c - 1.0) > 1e-6 for c in layer.tint):
            out["tint"] = rgb(layer.tint)
        return out
    if kind == "DIFFUSE":
        return {"type": "diffuse", "color": _colour(layer.color, layer.color_texture, images, layer)}
    if kind == "NULL":
        return {"type": "null"}
    raise StackError(f"unknown interface kind {kind!r}")


def _axis(layer, param, images=None):
    """An axis parameter as entered (the renderer normalises it); a zero vector means the
    schema's default. Its texture replaces it (decoded by the renderer like a normal map)."""
    image = getattr(layer, param.texture_prop)
    if image is not None and images is not None:
        tex = images.texture(image)
        if tex is not None:
            return _labelled(images, tex, _source(layer, image))
    axis = [f32(v) for v in getattr(layer, param.prop)]
    return axis if any(axis) else list(param.default)


def phase_json(layer, images=None) -> dict:
    """The medium's phase function, from its row in backend/layered/phase_schema.py."""
    kind = BY_ENUM[layer.phase]
    out = {"type": kind.name}
    for p in kind.params:
        if p.kind == "choice":
            out[p.key] = getattr(layer, p.prop).lower()
        elif p.kind == "axis":
            out[p.key] = _axis(layer, p, images)
        else:
            out[p.key] = f32(getattr(layer, p.prop))
    return out


def _density(layer, images):
    """σt: grey (a number) or chromatic (RGB); a texture multiplies either."""
    if layer.use_chromatic:
        value = rgb(layer.sigma_t_rgb)
        if layer.sigma_t_texture is not None and images is not None:
            tex = images.texture(layer.sigma_t_texture, scale=value)
            if tex is not None:
                return _labelled(images, tex, _source(layer, layer.sigma_t_texture))
        return value
    return _scalar(f32(layer.sigma_t), layer.sigma_t_texture, images, layer=layer)


def is_clear(layer) -> bool:
    """A medium with zero extinction (and no density texture) neither scatters nor absorbs."""
    density = any(layer.sigma_t_rgb) if layer.use_chromatic else layer.sigma_t != 0.0
    return not density and layer.sigma_t_texture is None


def medium_json(layer, images) -> dict:
    out = {"thickness": _scalar(f32(layer.thickness), layer.thickness_texture, images, layer=layer),
           "sigma_t": _density(layer, images)}
    clear = is_clear(layer)
    if clear:
        return out
    out["albedo"] = _colour(layer.albedo, layer.albedo_texture, images, layer)
    out["phase"] = phase_json(layer, images)
    return out


def _opaque(itf: dict) -> bool:
    kind = itf.get("type")
    if kind in ("conductor", "diffuse"):
        return True
    if kind == "layered":
        inner = itf.get("interfaces") or []
        return bool(inner) and _opaque(inner[-1])
    return False


def _first_opaque(interfaces: list[dict]) -> int | None:
    for i, itf in enumerate(interfaces):
        if _opaque(itf):
            return i
    return None


def stack_json(material, images, visiting: tuple = (), *, linked=None) -> dict:
    """The material JSON of a material with ``lamina.use_stack``; nested materials recurse.

    ``linked(material)``: the JSON to write instead of the stack, or None — export passes
    ``preset_link.linked_json`` (a stack unchanged since a preset was applied is written as that
    preset's own material JSON); without it the stack is always written as edited (the preset
    link's fingerprint).
    """
    if material.name in visiting:
        chain = " → ".join([*visiting, material.name])
        raise StackError(f"nested materials form a cycle: {chain}")
    if linked is not None:
        doc = linked(material)
        if doc is not None:
            return doc
    settings = material.lamina
    layers = list(settings.layers)
    if not layers:
        # Callers prefix the material being exported; only a nested one needs its own name.
        if visiting:
            raise StackError(f"nested material '{material.name}' has an empty layer stack")
        raise StackError("the layer stack is empty (add a layer or apply a preset)")
    visiting = (*visiting, material.name)
    interfaces = [interface_json(layer, images, visiting, linked) for layer in layers]
    cut = _first_opaque(interfaces)
    if cut is not None and cut < len(layers) - 1:
        # Nothing below an opaque interface is ever reached; the renderer would refuse the stack.
        # The panel warns (stack_check.py); the render leaves those interfaces out and says so.
        dropped = ", ".join(f"'{layer.name}'" for layer in layers[cut + 1:])
        if getattr(images, "notes", None) is not None:
            images.notes.append(f"material '{material.name}': interface(s) {dropped} below the opaque "
                                f"'{layers[cut].name}' are never reached (left out)")
        layers, interfaces = layers[:cut + 1], interfaces[:cut + 1]
    if len(layers) == 1:
        out = interfaces[0]
    else:
        out = {"type": "layered", "interfaces": interfaces,
               "media": [medium_json(layer, images) for layer in layers[:-1]]}
    if settings.emission_strength > 0 and any(settings.emission_color):
        s = float(settings.emission_strength)
        out = dict(out)
        out["emission"] = [f32(c * s) for c in rgb(settings.emission_color)]
    return out
