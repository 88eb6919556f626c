"""A material's Lamina layer stack (``Material.lamina``) → material JSON (docs/materials.md).

N interfaces with N−1 media give ``{"type": "layered", "interfaces": [...], "media": [...]}``;
a stack of one interface is written as that interface's own material type.
"""
from __future__ import annotations

from ..util import f32, rgb


class StackError(Exception):
    """A stack that cannot be exported (empty, or a nested material cycle)."""


def alpha(r: float) -> float:
    """Blender perceptual roughness → microfacet α (as Cycles: α = r²)."""
    return f32(float(r) * float(r))


def _scalar(value: float, image, images, *, squared: bool = False):
    if image is not None and images is not None:
        tex = images.texture(image, scale=value, squared=squared)
        if tex is not None:
            return tex
    return value


def _colour(value, image, images):
    if image is not None and images is not None:
        tex = images.texture(image, scale=rgb(value))
        if tex is not None:
            return tex
    return rgb(value)


def _microfacet(layer, images) -> dict:
    out = {"roughness": _scalar(alpha(layer.roughness), layer.roughness_texture, images, squared=True)}
    if layer.use_anisotropy:
        out["roughness_v"] = alpha(layer.roughness_v)
    out["distribution"] = layer.distribution.lower()
    return out


def interface_json(layer, images, visiting: tuple) -> dict:
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
        return {"type": "diffuse", "color": _colour(layer.color, layer.color_texture, images)}
    if kind == "NULL":
        return {"type": "null"}
    if kind == "MATERIAL":
        nested = layer.material
        if nested is None:
            raise StackError(f"interface '{layer.name or 'Nested'}' has no material set")
        return stack_json(nested, images, visiting)
    raise StackError(f"unknown interface kind {kind!r}")


def _axis(layer) -> list[float]:
    """The axis as entered (the renderer normalises it); a zero vector means +X (the default)."""
    axis = [f32(v) for v in layer.flake_orientation]
    return axis if any(axis) else [1.0, 0.0, 0.0]


def medium_json(layer, images) -> dict:
    out = {"thickness": f32(layer.thickness),
           "sigma_t": _scalar(f32(layer.sigma_t), layer.sigma_t_texture, images)}
    clear = layer.sigma_t == 0.0 and layer.sigma_t_texture is None
    if clear:
        return out
    out["albedo"] = _colour(layer.albedo, layer.albedo_texture, images)
    if layer.phase == "HG":
        out["phase"] = {"type": "hg", "g": f32(layer.hg_g)}
    elif layer.phase == "MICROFLAKE":
        out["phase"] = {"type": "microflake", "stddev": f32(layer.flake_stddev), "orientation": _axis(layer)}
    elif layer.phase == "VMF":
        out["phase"] = {"type": "vmf", "kappa": f32(layer.vmf_kappa)}
    elif layer.phase == "SGGX":
        out["phase"] = {"type": "sggx", "shape": layer.sggx_shape.lower(), "orientation": _axis(layer),
                        "roughness": f32(layer.sggx_roughness)}
    else:
        out["phase"] = {"type": "isotropic"}
    return out


def stack_json(material, images, visiting: tuple = ()) -> dict:
    """The material JSON of a material with ``lamina.use_stack``; nested materials recurse."""
    if material.name in visiting:
        chain = " → ".join([*visiting, material.name])
        raise StackError(f"nested materials form a cycle: {chain}")
    visiting = (*visiting, material.name)
    settings = material.lamina
    layers = list(settings.layers)
    if not layers:
        raise StackError(f"material '{material.name}' has an empty layer stack")
    interfaces = [interface_json(layer, images, visiting) for layer in layers]
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
