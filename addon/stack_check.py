"""Warnings for odd layer stacks, computed on the exported material JSON (no bpy).

The material panel shows them; the checks read the same JSON the renderer gets, so what is
flagged is what will be rendered. Each finding is ``(level, message)`` with level "ERROR"
(cannot render as meant) or "WARNING"/"INFO" (renders, but probably not what was meant).
"""
from __future__ import annotations

OPAQUE = ("conductor", "diffuse")
THICK_OPTICAL_DEPTH = 30.0       # exp(−30) ≈ 1e−13: nothing below such a slab is ever seen


def _value(v):
    """A constant, or the texture's scale (a texture reference is a dict)."""
    if isinstance(v, dict):
        return v.get("scale", 1.0)
    return v


def check_material(mat: dict) -> list[tuple[str, str]]:
    if mat.get("type") != "layered":
        return []
    out: list[tuple[str, str]] = []
    interfaces = mat.get("interfaces", [])
    media = mat.get("media", [])
    n = len(interfaces)
    for i, itf in enumerate(interfaces[:-1]):
        kind = itf.get("type")
        if kind in OPAQUE:
            out.append(("WARNING", f"Interface {i + 1} ({kind}) is opaque: the "
                                   f"{n - 1 - i} interface(s) below it are never reached "
                                   f"(renders leave them out)"))
            break
    last = interfaces[-1].get("type") if interfaces else None
    if last in ("dielectric", "null"):
        out.append(("INFO", "The bottom interface transmits: light leaving the stack at the bottom "
                            "passes into the object (thin-slab or glass behaviour)"))
    if interfaces and interfaces[0].get("type") == "null" and n > 1 and media:
        m0 = media[0]
        if _value(m0.get("sigma_t", 0)) in (0, [0, 0, 0]):
            out.append(("INFO", "A null top interface over a clear medium does nothing"))
    above = 1.0
    for i, itf in enumerate(interfaces):
        if itf.get("type") == "dielectric":
            ior = itf.get("ior", 1.5)
            if abs(ior - above) < 1e-6:
                out.append(("INFO", f"Interface {i + 1} has the same IOR as the medium above "
                                    f"({ior:g}): it is invisible, like a null interface"))
            above = ior
    for i, med in enumerate(media):
        sigma = _value(med.get("sigma_t", 0.0))
        thickness = _value(med.get("thickness", 1.0))
        if isinstance(sigma, list):            # chromatic: the least extinguished channel decides
            sigma = min(sigma) if sigma else 0.0
        if isinstance(thickness, list):
            thickness = thickness[0] if thickness else 1.0
        tau = float(sigma) * float(thickness)
        if thickness == 0 and sigma:
            out.append(("INFO", f"Medium {i + 1} has zero thickness: its density has no effect"))
        if tau > THICK_OPTICAL_DEPTH:
            out.append(("WARNING", f"Medium {i + 1} is optically very thick (σt·d = {tau:.3g}): "
                                   f"the interfaces below it contribute nothing"))
    return out

