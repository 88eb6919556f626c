"""Cycles/EEVEE shader node trees → Lamina materials (for materials without a Lamina stack).

Translated: Principled BSDF (dielectric base as a specular-over-diffuse stack, metallic as a
conductor, transmission as glass, coat as one more interface on top, emission), Diffuse, Glossy,
Metallic, Glass and Refraction BSDF, Emission; Image Texture nodes plugged into colour and
roughness inputs. Everything else is listed in ``notes`` (one warning per export), never
silently dropped; the value typed into the socket is used instead.
"""
from __future__ import annotations

from ..util import f0_to_conductor_k, rgb
from . import baked
from .stack import alpha

CLEAR_MEDIUM = {"thickness": 1.0, "sigma_t": 0.0}
DEFAULT_MATERIAL = {"type": "diffuse", "color": [0.8, 0.8, 0.8]}


def _distribution(node) -> str:
    return "beckmann" if getattr(node, "distribution", "") == "BECKMANN" else "ggx"


def label(node) -> str:
    """A node as users see it: its name, plus its type when renamed."""
    return node.name if node.name == node.bl_label else f"{node.name} ({node.bl_label})"


def _follow(socket):
    """The node and output socket feeding ``socket`` (through reroutes), or (None, None)."""
    while socket is not None and socket.is_linked:
        links = [l for l in socket.links if l.is_valid and not l.is_muted]
        if not links:
            return None, None
        node = links[0].from_node
        if node.bl_idname == "NodeReroute":
            socket = node.inputs[0]
            continue
        if node.mute:
            return None, None
        return node, links[0].from_socket
    return None, None


class NodeTranslator:
    def __init__(self, images, notes: list[str]):
        self.images = images
        self.notes = notes
        self._where = ""
        self._material = None
        #: (node, input name) of every input fed by something other than an image texture that
        #: a baked image could stand for (ops/bake.py bakes them; export/baked.py finds them).
        self.bakeable: list = []

    def note(self, what: str) -> None:
        self.notes.append(f"{self._where}: {what}" if self._where else what)

    # ---------------------------------------------------------------- entry points

    def material(self, mat) -> dict:
        self._where = f"material '{mat.name}'"
        self._material = mat
        tree = mat.node_tree if getattr(mat, "node_tree", None) is not None else None
        if tree is None or not _uses_nodes(mat):
            return {"type": "diffuse", "color": rgb(mat.diffuse_color)}
        out = tree.get_output_node("CYCLES") or tree.get_output_node("ALL")
        if out is None:
            self.note("no Material Output node (grey diffuse used)")
            return dict(DEFAULT_MATERIAL)
        node, _ = _follow(out.inputs["Surface"])
        if node is None:
            return {"type": "diffuse", "color": [0.0, 0.0, 0.0]}   # nothing connected renders black
        if out.inputs.get("Displacement") is not None and out.inputs["Displacement"].is_linked:
            self.note("displacement (ignored)")

        return self.shader(node)

    def shader(self, node) -> dict:
        kind = node.bl_idname
        handler = {
            "ShaderNodeBsdfPrincipled": self.principled,
            "ShaderNodeBsdfDiffuse": self.diffuse,
            "ShaderNodeBsdfAnisotropic": self.glossy,    # "Glossy BSDF" since 4.0
            "ShaderNodeBsdfGlossy": self.glossy,
            "ShaderNodeBsdfMetallic": self.metallic,
            "ShaderNodeBsdfGlass": self.glass,
            "ShaderNodeBsdfRefraction": self.glass,
            "ShaderNodeEmission": self.emission,
            "ShaderNodeMixShader": self.mix_shader,
            "ShaderNodeAddShader": self.add_shader,
        }.get(kind)
        if handler is None:
            self.note(f"{label(node)} (not supported: grey diffuse used)")
            return dict(DEFAULT_MATERIAL)
        out = handler(node)
        if kind not in ("ShaderNodeEmission", "ShaderNodeMixShader", "ShaderNodeAddShader"):
            self._normal_map(node, out)
        return out

    # ---------------------------------------------------------------- Mix / Add Shader

    #: Nested Mix / Add Shaders the backend resolves (backend/materials/mix.py MAX_DEPTH).
    MIX_DEPTH = 4

    def mix_shader(self, node) -> dict:
        """(1 − Fac)·first + Fac·second (backend/materials/mix.py)."""
        factor = self.scalar(node, "Fac", 0.5, allow_texture=True)
        if not isinstance(factor, dict):
            factor = min(max(factor, 0.0), 1.0)
        return {"type": "mix", "factor": factor,
                "materials": [self._component(node, node.inputs[1]), self._component(node, node.inputs[2])]}

    def add_shader(self, node) -> dict:
        return {"type": "add",
                "materials": [self._component(node, node.inputs[0]), self._component(node, node.inputs[1])]}

    def _component(self, mixer, socket) -> dict:
        """One shader input of a Mix / Add Shader: nothing connected adds no light (black)."""
        src, _ = _follow(socket)
        black = {"type": "diffuse", "color": [0.0, 0.0, 0.0]}
        if src is None:
            return black
        self._mix_depth = getattr(self, "_mix_depth", 0) + 1
        try:
            if self._mix_depth > self.MIX_DEPTH and src.bl_idname in ("ShaderNodeMixShader", "ShaderNodeAddShader"):
                self.note(f"{label(src)} nested more than {self.MIX_DEPTH} deep under {mixer.name} (black used)")
                return black
            out = self.shader(src)
        finally:
            self._mix_depth -= 1
        if out.get("type") == "emission" or "emission" in out:
            self.note(f"{label(src)}: emission inside {mixer.name} (not rendered: a mixed shader "
                      f"does not emit in Lamina yet)")
            if out.get("type") == "emission":
                return black
            out = {k: v for k, v in out.items() if k not in ("emission", "emission_sides")}
        return out

    # ---------------------------------------------------------------- inputs

    def colour(self, node, name: str, *, multiply=None):
        sock = node.inputs.get(name)
        if sock is None:
            return [0.8, 0.8, 0.8]
        src, _ = _follow(sock)
        if src is None:
            return rgb(sock.default_value)
        tex = self._image_input(node, name, src)
        if tex is not None:
            return tex
        return rgb(sock.default_value)

    def scalar(self, node, name: str, default: float = 0.0, *, allow_texture: bool = False,
               squared: bool = False):
        sock = node.inputs.get(name)
        if sock is None:
            return default
        value = float(sock.default_value)
        src, _ = _follow(sock)
        if src is None:
            return alpha(value) if squared else value
        if allow_texture:
            tex = self._image_input(node, name, src, squared=squared)
            if tex is not None:
                return tex
        else:
            self.note(f"{label(src)} → {node.name}.{name} (only constants here: value used)")
        return alpha(value) if squared else value

    def _baked(self, node, name: str, src, what: str, squared: bool = False):
        """The baked image standing for the procedural ``src`` → ``node.name``, or None (and a
        note naming the input, with ``what`` Lamina uses instead)."""
        if src.bl_idname == "ShaderNodeShaderToRGB":
            # EEVEE-only: Cycles renders it black, so baking (through Cycles) cannot help.
            self.note(f"{label(src)} → {node.name}.{name} (EEVEE only, rendered by neither Cycles nor "
                      f"Lamina: {what})")
            return None
        self.bakeable.append((node, name))
        image, why = baked.lookup(self._material, node, name)
        if image is None:
            self.note(f"{label(src)} → {node.name}.{name} ({why or 'procedural, not baked'}: {what}; "
                      f"Bake Procedural Textures in Lamina's material panel)")
            return None
        return self.images.label(self.images.texture(image, squared=squared),
                                 f"image '{image.name}' (baked from {label(src)} → {node.name}.{name})")

    def _image_input(self, node, name: str, src, squared: bool = False):
        if src.bl_idname != "ShaderNodeTexImage":
            return self._baked(node, name, src, "value used", squared)
        if src.image is None:
            return None
        if src.inputs["Vector"].is_linked:
            self.note(f"{src.name}: texture mapping (ignored; the active UV map is used)")
        if src.projection != "FLAT" or src.extension not in ("REPEAT",):
            self.note(f"{src.name}: {src.projection.lower()} projection / {src.extension.lower()} "
                      f"extension (rendered as flat, repeating)")
        return self.images.label(self.images.texture(src.image, squared=squared),
                                 f"node '{src.name}' (image '{src.image.name}' → {node.name}.{name})")

    def _unused(self, node, name: str, ok) -> None:
        """Note an input whose value Lamina cannot represent (``ok(value)`` says it is harmless)."""
        sock = node.inputs.get(name)
        if sock is None:
            return
        if sock.is_linked:
            self.note(f"{node.name}.{name} input (not supported)")
        elif not ok(sock.default_value):
            self.note(f"{node.name}.{name} (not supported)")

    # ---------------------------------------------------------------- shaders

    def diffuse(self, node) -> dict:
        self._unused(node, "Roughness", lambda v: v == 0.0)
        return {"type": "diffuse", "color": self.colour(node, "Color")}

    def glossy(self, node) -> dict:
        # Cycles' Glossy BSDF reflects its colour at every angle; a conductor with that
        # normal-incidence reflectance is the closest Lamina material.
        self._unused(node, "Anisotropy", lambda v: v == 0.0)
        colour = self.colour(node, "Color")
        out = {"type": "conductor", "roughness": self.scalar(node, "Roughness", 0.5, allow_texture=True, squared=True),
               "distribution": _distribution(node)}
        # Cycles' Glossy BSDF (multiscatter GGX, constant Fresnel) reflects its colour under
        # uniform light; the conductor's F0 is chosen to give that albedo (principled.py).
        if not isinstance(colour, dict) and getattr(node, "distribution", "MULTI_GGX") == "MULTI_GGX":
            colour = self._matched_f0(colour, node, "Roughness", lambda c, r: c)
        return self._conductor_from_f0(out, colour)

    def _matched_f0(self, colour, node, rough_name: str, target_of):
        from .principled import conductor_f0
        r = float(node.inputs[rough_name].default_value)
        target = target_of(colour, r)
        f0, clamped = conductor_f0(target, min(max(r, 0.0), 1.0))
        if clamped:
            self.note(f"{node.name}: an albedo the conductor cannot reach (clamped)")
        return [round(float(v), 6) for v in f0]

    def metallic(self, node) -> dict:
        self._unused(node, "Anisotropy", lambda v: v == 0.0)
        out = {"type": "conductor", "roughness": self.scalar(node, "Roughness", 0.5, allow_texture=True, squared=True),
               "distribution": _distribution(node)}
        if getattr(node, "fresnel_type", "F82") == "PHYSICAL_CONDUCTOR":
            out["eta"] = self.colour(node, "IOR")
            out["k"] = self.colour(node, "Extinction")
            if isinstance(out["eta"], dict) or isinstance(out["k"], dict):
                self.note(f"{node.name}: textured IOR/Extinction (value used)")
                out["eta"] = rgb(node.inputs["IOR"].default_value)
                out["k"] = rgb(node.inputs["Extinction"].default_value)
            return out
        self._unused(node, "Edge Tint", lambda v: all(abs(c - 1.0) < 1e-6 for c in v[:3]))
        colour = self.colour(node, "Base Color")
        if not isinstance(colour, dict):
            from .principled import cycles_metal
            colour = self._matched_f0(colour, node, "Roughness",
                                      lambda c, r: cycles_metal(c, min(max(r, 0.0), 1.0)).mean(axis=1))
        return self._conductor_from_f0(out, colour)

    def glass(self, node) -> dict:
        out = {"type": "dielectric", "ior": float(node.inputs["IOR"].default_value),
               "roughness": self.scalar(node, "Roughness", 0.0, allow_texture=True, squared=True),
               "distribution": _distribution(node)}
        tint = self.colour(node, "Color")
        if isinstance(tint, dict) or any(abs(c - 1.0) > 1e-6 for c in tint):
            out["transmission_color"] = tint
        if node.bl_idname == "ShaderNodeBsdfRefraction":
            self.note(f"{node.name}: Refraction BSDF rendered as glass (with reflection)")
        return out

    def emission(self, node) -> dict:
        colour = self.colour(node, "Color")
        if isinstance(colour, dict):
            self.note(f"{node.name}: textured emission colour (value used)")
            colour = rgb(node.inputs["Color"].default_value)
        return {"type": "emission", "color": colour,
                "strength": float(self.scalar(node, "Strength", 1.0))}

    def principled(self, node) -> dict:
        """Principled BSDF → a stack whose albedo matches Cycles' (principled.py)."""
        from .principled import principled_material
        self._unused(node, "Alpha", lambda v: v >= 1.0)
        self._unused(node, "Subsurface Weight", lambda v: v == 0.0)
        self._unused(node, "Anisotropic", lambda v: v == 0.0)
        self._unused(node, "Thin Film Thickness", lambda v: v == 0.0)
        self._unused(node, "Diffuse Roughness", lambda v: v == 0.0)
        self._unused(node, "Coat Normal", lambda v: True)
        value = lambda name, default=0.0: self._value(node, name, default)       # noqa: E731
        colour = lambda name: rgb(node.inputs[name].default_value)              # noqa: E731
        base_colour = self.colour(node, "Base Color")
        roughness = self.scalar(node, "Roughness", 0.5, allow_texture=True, squared=True)
        params = {"base_color": base_colour if not isinstance(base_colour, dict) else [0.5, 0.5, 0.5],
                  "metallic": value("Metallic"), "roughness": value("Roughness", 0.5),
                  "ior": value("IOR", 1.5), "specular_ior_level": value("Specular IOR Level", 0.5),
                  "specular_tint": colour("Specular Tint"),
                  "transmission": value("Transmission Weight"),
                  "coat_weight": value("Coat Weight"), "coat_roughness": value("Coat Roughness", 0.03),
                  "coat_ior": value("Coat IOR", 1.5), "coat_tint": colour("Coat Tint"),
                  "sheen_weight": value("Sheen Weight"), "sheen_roughness": value("Sheen Roughness", 0.5),
                  "sheen_tint": colour("Sheen Tint"), "distribution": _distribution(node)}
        emission = self._emission(node)
        textured_emission = isinstance(emission, dict)
        if emission is not None and not textured_emission:
            params["emission"] = emission
        trans = params["transmission"]
        if 0.0 < trans < 1.0 and params["metallic"] == 0.0 and emission is None:
            # Partly transmissive: a Mix of its opaque and its glass translation by the weight
            # (Cycles mixes the two lobes linearly too).
            parts, notes = [], []
            for t in (0.0, 1.0):
                part, part_notes = principled_material(dict(params, transmission=t))
                parts.append(self._textured_principled(node, part, roughness, base_colour, params))
                notes += [n for n in part_notes if n not in notes]
            out = {"type": "mix", "factor": trans, "materials": parts}
        else:
            out, notes = principled_material(params)
            out = self._textured_principled(node, out, roughness, base_colour, params)
        for text in notes:
            self.note(f"{node.name}: {text}")
        if textured_emission:
            out["emission"] = emission
        return out

    def _textured_principled(self, node, out: dict, roughness, base_colour, params) -> dict:
        if isinstance(roughness, dict):
            self.note(f"{node.name}: textured Roughness (albedo matched at its value {params['roughness']:g})")
            self._set_roughness(out, roughness)
        if isinstance(base_colour, dict):
            out = self._textured_base(node, out, base_colour)
        return out

    def _value(self, node, name: str, default: float = 0.0) -> float:
        sock = node.inputs.get(name)
        if sock is None:
            return default
        if sock.is_linked and _follow(sock)[0] is not None:
            self.note(f"{node.name}.{name} is connected (not supported; value used)")
        return float(sock.default_value)

    @staticmethod
    def _set_roughness(out: dict, roughness) -> None:
        """The base lobe's roughness texture (the interface under a coat, else the top one)."""
        if out.get("type") == "layered":
            itfs = out["interfaces"]
            target = itfs[-2] if itfs[-1].get("type") == "diffuse" else itfs[-1]
            target["roughness"] = roughness
        else:
            out["roughness"] = roughness

    def _textured_base(self, node, out: dict, texture: dict) -> dict:
        """A textured base colour: the body's albedo is the texture times the mapping's gain at
        mid-grey (the table maps colours nonlinearly; this is exact at 0.5)."""
        self.note(f"{node.name}: textured Base Color (albedo matched at mid-grey)")
        tex = dict(texture)
        source = self.images.labels.get(id(texture))
        if source is not None:
            self.images.label(tex, source[1])
        if out.get("type") == "layered" and out["interfaces"][-1].get("type") == "diffuse":
            gain = [c / 0.5 for c in out["interfaces"][-1]["color"]]
            scale = tex.get("scale", 1.0)
            scale = scale if isinstance(scale, list) else [scale] * 3
            tex["scale"] = [round(a * b, 6) for a, b in zip(scale, gain)]
            out["interfaces"][-1]["color"] = tex
        elif out.get("type") == "dielectric":
            self.note(f"{node.name}: textured Base Color on glass (mid-grey tint used)")
        elif out.get("type") == "conductor":
            self.note(f"{node.name}: textured metal colour (mid-grey used)")
        return out

    # ---------------------------------------------------------------- helpers

    def _weight(self, node, name: str, threshold: float | None = 0.5) -> float:
        sock = node.inputs.get(name)
        if sock is None:
            return 0.0
        if sock.is_linked:
            self.note(f"{node.name}.{name} is connected (not supported; value used)")
        value = float(sock.default_value)
        if threshold is not None and 0.0 < value < 1.0:
            self.note(f"{node.name}.{name} {value:g} (rounded to {0 if value < threshold else 1})")
        return value

    def _emission(self, node):
        strength = float(node.inputs["Emission Strength"].default_value)
        if node.inputs["Emission Strength"].is_linked:
            self.note(f"{node.name}.Emission Strength is connected (value used)")
        if strength <= 0.0:
            return None
        colour = self.colour(node, "Emission Color")
        if isinstance(colour, dict):
            source = self.images.labels.get(id(colour))
            colour = dict(colour)
            if source is not None:
                self.images.label(colour, source[1])
            scale = colour.get("scale", 1.0)
            colour["scale"] = [strength * s for s in (scale if isinstance(scale, list) else [scale] * 3)]
            return colour
        if not any(colour):
            return None
        return [c * strength for c in colour]

    def _normal_map(self, node, out: dict) -> None:
        """A BSDF's Normal input: a Normal Map node in tangent space fed by an image texture
        becomes the material's ``normal`` (+ ``normal_strength``), a Bump node fed by an image
        texture its ``bump`` (materials/normal.py in the backend), a Bump node over a Normal Map
        both; anything else is named in the warning."""
        sock = node.inputs.get("Normal")
        if sock is None or not sock.is_linked:
            return
        src, _ = _follow(sock)
        if src is None:
            return
        if src.bl_idname == "ShaderNodeBump":
            self._bump(src, out)
            inner, _ = _follow(src.inputs["Normal"])
            if inner is None:
                return
            src, node = inner, src                   # the Bump node's own Normal input
        if src.bl_idname != "ShaderNodeNormalMap":
            self.note(f"{label(src)} → {node.name}.Normal (not supported: the surface normal used)")
            return
        self._tangent_normal_map(src, out)

    def _tangent_normal_map(self, src, out: dict) -> None:
        if src.space != "TANGENT":
            self.note(f"{src.name}: {src.space.lower()} space normal map (only tangent space: "
                      f"the surface normal used)")
            return
        colour, _ = _follow(src.inputs["Color"])
        if colour is None:
            return                                   # an unconnected colour is the flat normal
        if src.uv_map:
            self.note(f"{src.name}: UV map '{src.uv_map}' (the active UV map is used)")
        if colour.bl_idname != "ShaderNodeTexImage":
            tex = self._baked(src, "Color", colour, "the surface normal used")
        elif colour.image is None:
            return
        else:
            if colour.inputs["Vector"].is_linked:
                self.note(f"{colour.name}: texture mapping (ignored; the active UV map is used)")
            tex = self.images.texture(colour.image)
            self.images.label(tex, f"node '{colour.name}' (image '{colour.image.name}' → {src.name}.Color)")
        if tex is None:
            return
        out["normal"] = tex
        strength_sock = src.inputs["Strength"]
        if strength_sock.is_linked:
            self.note(f"{src.name}.Strength is connected (value used)")
        strength = float(strength_sock.default_value)
        if strength != 1.0:
            out["normal_strength"] = max(strength, 0.0)

    def _bump(self, src, out: dict) -> None:
        """A Bump node whose Height comes from an image texture's Color (its luminance, as Blender
        converts a colour to a number) → ``"bump"``. The backend differentiates the bilinear texture exactly, where Cycles
        takes differences over a fraction (Filter Width) of the pixel footprint: the same for
        textures seen larger than their texels."""
        height, socket = _follow(src.inputs["Height"])
        if height is None:
            return                                   # a constant height tilts nothing
        if height.bl_idname != "ShaderNodeTexImage":
            tex = self._baked(src, "Height", height, "the bump is left out")
        elif height.image is None:
            return
        elif socket.name != "Color":
            self.note(f"{height.name}.{socket.name} → {src.name}.Height (only the Color output: "
                      f"the bump is left out)")
            return
        else:
            if height.inputs["Vector"].is_linked:
                self.note(f"{height.name}: texture mapping (ignored; the active UV map is used)")
            tex = self.images.texture(height.image)          # a scalar: the image's luminance
            self.images.label(tex, f"node '{height.name}' (image '{height.image.name}' → {src.name}.Height)")
        if tex is None:
            return
        for name in ("Strength", "Distance"):
            if src.inputs[name].is_linked:
                self.note(f"{src.name}.{name} is connected (value used)")
        bump = {"height": tex, "distance": float(src.inputs["Distance"].default_value),
                "strength": min(max(float(src.inputs["Strength"].default_value), 0.0), 1.0)}
        if src.invert:
            bump["invert"] = True
        out["bump"] = bump

    def _conductor_from_f0(self, out: dict, colour) -> dict:
        if isinstance(colour, dict):
            self.note("textured metal colour (its scale used)")
            colour = colour.get("scale", [0.8, 0.8, 0.8])
            if not isinstance(colour, list):
                colour = [float(colour)] * 3
        out["eta"] = [1.0, 1.0, 1.0]
        out["k"] = f0_to_conductor_k(colour)
        return out


def volume_note(mat) -> str | None:
    """A note if the material's output has a Volume shader connected (Lamina renders surfaces)."""
    tree = getattr(mat, "node_tree", None)
    if tree is None or not _uses_nodes(mat):
        return None
    out = tree.get_output_node("CYCLES") or tree.get_output_node("ALL")
    sock = out.inputs.get("Volume") if out is not None else None
    node = _follow(sock)[0] if sock is not None else None
    if node is None:
        return None
    return f"material '{mat.name}': {label(node)} → Volume output (volumes are not rendered: ignored)"


def _uses_nodes(mat) -> bool:
    # Material.use_nodes is deprecated in 5.0 (always on); read it quietly where it exists.
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return bool(getattr(mat, "use_nodes", True))
