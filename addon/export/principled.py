"""Principled BSDF → a Lamina material with Cycles' directional albedo (no bpy, no BSDF code).

Lamina renders a non-metallic Principled BSDF as a physical stack: a rough dielectric interface
(the specular layer) over a Lambertian body. Physically, light that enters such a stack is
partly reflected back down at the inside of the interface (total internal reflection) and the
rough interface loses some energy at every crossing; Cycles' Principled instead scales its
diffuse layer by one minus the specular layer's albedo and keeps the rest. With the base colour
as the body's albedo the stack is therefore darker and more saturated (0.66× for the default
grey). So the body's albedo ρ′ is chosen per channel such that the stack's albedo under uniform
light (the cosine-weighted mean of its directional albedo) equals that of Cycles' Principled at
the same settings.

Everything comes from ``principled_table.json`` (``tools/gen_principled_table.py``; the method is
written there): Cycles' layer albedos measured per viewing-angle bin, and the Lamina interface's
reflectance and transmittance from its own BSDF. This module interpolates those tables and
combines them with Cycles' layering rules (``intern/cycles/kernel/svm/closure.h``: each layer
scales the layers below by one minus its albedo; coat tint ``tint^(1/cos θt)``; metallic and
transmission weights mix linearly). The stack side uses one exact relation: a dielectric over a
Lambertian body of albedo ρ′ reflects R + T·K with K = ρ′T↓/(1 − ρ′R↓) (T↓, R↓: the interface's
cosine-weighted transmittance and reflectance from below), hence ρ′ = K/(T↓ + K·R↓).

What is matched, and how (docs/blender.md, "Principled BSDF"):

* base colour, roughness, IOR, Specular IOR Level (Cycles' own IOR remapping), Specular Tint
  (its albedo; the highlight itself stays untinted): exact up to table interpolation;
* metallic 1: a conductor whose normal-incidence reflectance is chosen so its albedo equals
  Cycles' F82 metal of that base colour; 0 < metallic < 1: the dielectric's index is raised so its
  reflectance at normal incidence is the mix of the metal's and the dielectric's, and the body
  albedo matches the mixed albedo per channel (an approximation: one lobe, not two);
* coat (weight, roughness, IOR, tint): a dielectric interface on top; the base's index becomes
  coat IOR × IOR so its own reflection keeps Cycles' strength; a coat weight below 1 lowers the
  coat's reflectance at normal incidence to weight × its value; the coat tint's absorption goes
  into the body colour (or the metal's reflectance), the base being chosen with the adding rule
  for two layers (``_coated``);
* transmission: weight ≥ ½ renders glass (transmission colour √base per crossing, as Cycles);
  below, the opaque stack whose albedo is the weighted mix of the glass's (what it reflects plus
  what it lets through, for a closed object under uniform light) and the opaque part's;
* sheen: its albedo (Cycles' measured sheen layer) is added to the body albedo; the grazing
  lobe itself is not reproduced;
* emission: colour × strength × the mean attenuation of the sheen and coat layers above it.

A target the stack cannot reach (an albedo above what the rough interface lets through, or a
Specular Tint darker than the dielectric's own reflection) is clamped and named in the render's
warning.
"""
from __future__ import annotations

import json
import math
from functools import lru_cache
from pathlib import Path

import numpy as np

TABLE = Path(__file__).with_name("principled_table.json")
MAX_LOOP_GAIN = 0.9          # ρ′·R↓ stays below this: a convergent, low-variance inner walk
METAL_SPREAD = 1.8           # coated metals: how fast with roughness their reflection turns diffuse
GLASS_FROM = 0.5             # Transmission Weight from which the material renders as glass
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@lru_cache(maxsize=1)
def table() -> dict:
    doc = json.loads(TABLE.read_text(encoding="utf-8"))
    out = {k: (np.asarray(v, dtype=np.float64) if isinstance(v, list) else v) for k, v in doc.items()}
    return out


def _weights(axis: np.ndarray, x: float) -> tuple[int, float]:
    x = min(max(float(x), float(axis[0])), float(axis[-1]))
    i = int(np.clip(np.searchsorted(axis, x, side="right") - 1, 0, len(axis) - 2))
    t = (x - axis[i]) / (axis[i + 1] - axis[i])
    return i, t


def lookup(key: str, first: float, roughness: float, first_axis: str = "ior") -> np.ndarray:
    """Bilinear interpolation of table ``key`` at (first, roughness) (clamped to the grid)."""
    t = table()
    data = t[key]
    i, a = _weights(t[first_axis], first)
    j, b = _weights(t["roughness"], roughness)
    return ((1 - a) * (1 - b) * data[i, j] + a * (1 - b) * data[i + 1, j]
            + (1 - a) * b * data[i, j + 1] + a * b * data[i + 1, j + 1])


def f0_from_ior(ior: float) -> float:
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def ior_from_f0(f0: float) -> float:
    s = math.sqrt(min(max(f0, 0.0), 0.999))
    return (1.0 + s) / (1.0 - s)


def cycles_ior(ior: float, level: float) -> float:
    """Cycles' Specular IOR Level: F0 × 2·level, turned back into an index (closure.h)."""
    if abs(level - 0.5) < 1e-9:
        return ior
    eta = ior_from_f0(f0_from_ior(ior) * 2.0 * max(level, 0.0))
    return 1.0 / eta if ior < 1.0 else eta


# ----------------------------------------------------------------------------- Cycles' albedos

def cycles_specular(ior: float, roughness: float, tint) -> tuple[np.ndarray, np.ndarray]:
    """(per channel and bin: the specular layer's albedo (3, B); per bin: the layering weight
    1 − max over channels (B,)). Specular Tint scales Cycles' F0, linear in the tint."""
    e = lookup("cycles_specular", ior, roughness)
    w = lookup("cycles_specular_untinted_part", ior, roughness)
    tint = np.clip(np.asarray(tint, dtype=np.float64)[:3], 0.0, None)
    spec = w[None, :] + tint[:, None] * (e - w)[None, :]
    return spec, 1.0 - spec.max(axis=0)


def cycles_metal(base, roughness: float) -> np.ndarray:
    """Cycles' F82 metal albedo (3, B) for base colours (clamped to [0, 1]) as F0."""
    base = np.clip(np.asarray(base, dtype=np.float64)[:3], 0.0, 1.0)
    return np.stack([lookup("cycles_metal", f, roughness, "f0") for f in base])


def cycles_sheen(roughness: float) -> np.ndarray:
    t = table()
    i, a = _weights(t["sheen_roughness"], roughness)
    return (1 - a) * t["cycles_sheen"][i] + a * t["cycles_sheen"][i + 1]


# ----------------------------------------------------------------------------- Lamina inverses

def interface(ior: float, roughness: float) -> dict:
    return {"R": lookup("lamina_R", ior, roughness), "T": lookup("lamina_T", ior, roughness),
            "Rd": float(lookup("lamina_R_down", ior, roughness)),
            "Td": float(lookup("lamina_T_down", ior, roughness))}


def body_albedo(target: np.ndarray, itf: dict, bins=None) -> tuple[np.ndarray, bool]:
    """ρ′ (3,) of the Lambertian body under interface ``itf`` whose stack albedo (mean over
    ``bins``, default all) equals ``target`` (3,); and whether a channel had to be clamped."""
    sel = slice(None) if bins is None else bins
    R, T = itf["R"][sel].mean(), itf["T"][sel].mean()
    K = (np.asarray(target, dtype=np.float64) - R) / max(T, 1e-9)
    clamped = bool(np.any(K < -1e-4))
    K = np.maximum(K, 0.0)
    rho = K / np.maximum(itf["Td"] + K * itf["Rd"], 1e-9)
    limit = MAX_LOOP_GAIN / max(itf["Rd"], 1e-9)
    clamped |= bool(np.any(rho > limit))
    return np.minimum(rho, limit), clamped


def stack_albedo(rho, itf: dict) -> np.ndarray:
    """Per bin (3, B): the albedo of the interface over a Lambertian body ρ′ (the exact relation)."""
    rho = np.asarray(rho, dtype=np.float64)[:, None]
    K = rho * itf["Td"] / (1.0 - rho * itf["Rd"])
    return itf["R"][None, :] + itf["T"][None, :] * K


def conductor_f0(target: np.ndarray, roughness: float, bins=None) -> tuple[np.ndarray, bool]:
    """Per channel, the F0 of Lamina's η = 1 conductor whose albedo (mean over ``bins``) equals
    ``target``; whether a channel had to be clamped."""
    t = table()
    sel = slice(None) if bins is None else bins
    curve = np.array([lookup("lamina_conductor", f, roughness, "f0")[sel].mean() for f in t["f0"]])
    target = np.asarray(target, dtype=np.float64)
    clamped = bool(np.any(target > curve[-1] + 1e-4) or np.any(target < curve[0] - 1e-4))
    return np.interp(target, curve, t["f0"]), clamped


def _bins_inside(coat_ior: float) -> np.ndarray:
    """Bins (in cos²θ) that light refracted into a coat of this index reaches: cos²θ ≥ 1 − 1/n²."""
    b = int(table()["bins"])
    lo = 1.0 - 1.0 / max(coat_ior, 1.0) ** 2
    edges = np.linspace(0.0, 1.0, b + 1)
    keep = edges[1:] > lo + 1e-9
    return keep if keep.any() else np.ones(b, bool)


# ----------------------------------------------------------------------------- the mapping

def _rgb(v) -> list[float]:
    return [round(float(x), 6) for x in v]


def principled_material(p: dict, info: dict | None = None) -> tuple[dict, list[str]]:
    """The Lamina material for Principled settings ``p`` (plain numbers: base_color (3), metallic,
    roughness, ior, specular_ior_level, specular_tint (3), transmission, coat_weight,
    coat_roughness, coat_ior, coat_tint (3), sheen_weight, sheen_roughness, sheen_tint (3),
    emission (3, colour × strength)); returns (material JSON, notes about approximations).
    ``info`` (a dict) receives ``target``: Cycles' albedo under uniform light per channel."""
    notes: list[str] = []
    base = np.clip(np.asarray(p.get("base_color", (0.8, 0.8, 0.8)), dtype=np.float64)[:3], 0.0, None)
    rough = float(np.clip(p.get("roughness", 0.5), 0.0, 1.0))
    alpha = rough * rough
    eta = cycles_ior(float(p.get("ior", 1.5)), float(p.get("specular_ior_level", 0.5)))
    tint = p.get("specular_tint", (1.0, 1.0, 1.0))
    metallic = float(np.clip(p.get("metallic", 0.0), 0.0, 1.0))
    trans = float(np.clip(p.get("transmission", 0.0), 0.0, 1.0))
    coat_w = max(float(p.get("coat_weight", 0.0)), 0.0)
    sheen_w = max(float(p.get("sheen_weight", 0.0)), 0.0)
    t = table()
    eta_t = min(max(eta, float(t["ior"][0])), float(t["ior"][-1]))
    if abs(eta_t - eta) > 1e-6:
        notes.append(f"IOR {eta:g} (tabulated range {t['ior'][0]:g}–{t['ior'][-1]:g}: albedo matched at {eta_t:g})")

    # Cycles, per channel and viewing-angle bin: the base (metal / transmission / specular+diffuse).
    spec, layer_w = cycles_specular(eta_t, rough, tint)
    plastic = spec + layer_w[None, :] * base[:, None]
    if metallic > 0.0:
        metal = cycles_metal(base, rough)
    glass_r = cycles_specular(eta_t, rough, (1.0, 1.0, 1.0))[0]        # glass reflection (same Fresnel)
    target_base = plastic
    if trans > 0.0:
        # Under uniform light a closed glass object returns what it reflects plus what it lets
        # through (R + T = 1 for Cycles' energy-conserving glass), tinted by the base colour
        # (√base per crossing, two crossings).
        glass_total = glass_r + (1.0 - glass_r) * np.clip(base, 0.0, 1.0)[:, None]
        target_base = trans * glass_total + (1.0 - trans) * plastic
    if metallic > 0.0:
        target_base = metallic * metal + (1.0 - metallic) * target_base
    if any(abs(float(c) - 1.0) > 1e-6 for c in list(tint)[:3]):
        notes.append("Specular Tint (its albedo is matched; the highlight is not tinted)")

    # Layers above the base: coat, then sheen (Cycles' order from the top: sheen, coat).
    above_w = np.ones_like(layer_w)                 # attenuation of the base by the layers above
    above_add = np.zeros_like(target_base)          # what those layers reflect themselves
    coat = None
    if coat_w > 0.0:
        n_c = max(float(p.get("coat_ior", 1.5)), 1.0)
        r_c = float(np.clip(p.get("coat_roughness", 0.03), 0.0, 1.0))
        c_tint = np.clip(np.asarray(p.get("coat_tint", (1, 1, 1)), dtype=np.float64)[:3], 1e-4, None)
        w_eff = min(coat_w, 1.0)
        c_alb = w_eff * lookup("cycles_specular", n_c, r_c)
        mu = np.asarray(t["mu"], dtype=np.float64)
        cos_t = np.sqrt(1.0 - (1.0 - mu * mu) / (n_c * n_c))
        tint_pass = 1.0 + w_eff * (c_tint[:, None] ** (1.0 / cos_t[None, :]) - 1.0)
        above_add = above_add + c_alb[None, :]
        above_w = above_w * (1.0 - c_alb)
        base_scale = tint_pass
        coat = {"ior": n_c, "roughness": r_c, "weight": w_eff, "tint": c_tint}
        if coat_w > 1.0:
            notes.append(f"Coat Weight {coat_w:g} (rendered as 1)")
    else:
        base_scale = np.ones_like(target_base)
    sheen_alb = None
    if sheen_w > 0.0:
        s_tint = np.clip(np.asarray(p.get("sheen_tint", (1, 1, 1)), dtype=np.float64)[:3], 0.0, None)
        s = cycles_sheen(float(p.get("sheen_roughness", 0.5)))
        sheen_alb = sheen_w * s_tint[:, None] * s[None, :]
        notes.append("Sheen (its albedo is added to the body colour; the sheen lobe is not rendered)")
    # Cycles' albedo per channel and bin, then its mean (the albedo under uniform light).
    total = above_add + above_w[None, :] * base_scale * target_base
    emission_scale = above_w[None, :] * base_scale
    if sheen_alb is not None:
        sheen_w_layer = 1.0 - sheen_alb.max(axis=0)
        total = sheen_alb + sheen_w_layer[None, :] * total
        emission_scale = sheen_w_layer[None, :] * emission_scale
    target = total.mean(axis=1)
    if info is not None:
        info["target"] = target

    # Lamina: choose the stack.
    clamped = False
    if metallic >= 1.0 - 1e-6:
        kind = "metal"
    elif (1.0 - metallic) * trans >= GLASS_FROM:          # the glass's share of the mix
        kind = "glass"
    else:
        kind = "plastic"
    if kind == "glass" and coat is not None:
        notes.append("Coat on a transmissive surface (not rendered: glass without coat)")
    if 0.0 < trans < 1.0:
        notes.append(f"Transmission Weight {trans:g} (rendered as {'glass' if kind == 'glass' else 'opaque'}; "
                     f"albedo matched)")
    if 0.0 < metallic < 1.0 and kind == "plastic":
        notes.append(f"Metallic {metallic:g} (one dielectric lobe with the mixed reflectance; albedo matched)")

    dist = p.get("distribution", "ggx")
    if kind == "glass":
        out = {"type": "dielectric", "ior": round(eta, 6), "roughness": round(alpha, 6), "distribution": dist}
        colour = np.sqrt(np.clip(base, 0.0, 1.0))
        if np.any(np.abs(colour - 1.0) > 1e-6):
            out["transmission_color"] = _rgb(colour)
        layers = None
    elif kind == "metal":
        layers = ("metal", None)
    else:
        # A metallic mix raises the dielectric's reflectance at normal incidence.
        eta_l = eta_t
        if metallic > 0.0:
            f0_mix = metallic * float(np.clip(base, 0, 1) @ LUMINANCE) + (1.0 - metallic) * f0_from_ior(eta_t)
            eta_l = min(ior_from_f0(f0_mix), float(t["ior"][-1]))
        layers = ("plastic", eta_l)

    if layers is not None:
        base_kind, eta_l = layers
        if coat is None:
            if base_kind == "plastic":
                rho, clamped = body_albedo(target, interface(eta_l, rough))
                out = {"type": "layered",
                       "interfaces": [{"type": "dielectric", "ior": round(eta_l, 6), "roughness": round(alpha, 6),
                                       "distribution": dist}, {"type": "diffuse", "color": _rgb(rho)}],
                       "media": [{"thickness": 1.0, "sigma_t": 0.0}]}
            else:
                f0, clamped = conductor_f0(target, rough)
                out = _conductor(f0, alpha, dist, 1.0)
        else:
            out, clamped = _coated(target, coat, base_kind, eta_l, rough, alpha, dist)
    if clamped:
        notes.append("an albedo the Lamina stack cannot reach (clamped)")

    emission = np.asarray(p.get("emission", (0.0, 0.0, 0.0)), dtype=np.float64)[:3]
    if np.any(emission > 0.0):
        scale = emission_scale.mean(axis=1)
        out["emission"] = _rgb(emission * scale)
    return out, notes


def _conductor(f0, alpha: float, dist: str, eta_above: float) -> dict:
    f = np.clip(np.asarray(f0, dtype=np.float64), 0.0, 0.999)
    k = 2.0 * np.sqrt(f / (1.0 - f))              # η = 1: F0 = k²/(4 + k²)
    # Under a coat of index n the metal's index relative to the coat must be 1 + ik: η = n, k·n.
    return {"type": "conductor", "eta": _rgb([eta_above] * 3), "k": _rgb(k * eta_above),
            "roughness": round(alpha, 6), "distribution": dist}


def _coated(target, coat: dict, base_kind: str, eta_l: float, rough: float, alpha: float,
            dist: str) -> tuple[dict, bool]:
    """Coat interface over the base (Cycles' coat tint is part of ``target`` and so ends up in the
    body colour or the metal's reflectance, not in an absorbing medium). The base is chosen so the
    whole stack's albedo matches, with the adding rule for two layers: light refracted into the
    coat reaches the base within the refracted cone; what the base reflects specularly leaves the
    same way, what its body sends up is treated as diffuse light inside the coat (escaping with
    the coat's T↓, reflected back with its R↓ onto the base's albedo under diffuse light)."""
    n_c, w = coat["ior"], coat["weight"]
    n_eff = ior_from_f0(w * f0_from_ior(n_c)) if w < 1.0 else n_c
    top = interface(n_eff, coat["roughness"])
    inside = _bins_inside(n_eff)
    Rc, Tc = top["R"].mean(), top["T"].mean()
    target = np.asarray(target, dtype=np.float64)

    def solve(albedo_of, lo: float, hi: float) -> np.ndarray:
        """Per channel, the parameter in [lo, hi] whose stack albedo is ``target`` (bisection on
        a monotonic function); clamped at the ends."""
        a, b = np.full(3, lo), np.full(3, hi)
        for _ in range(40):
            m = 0.5 * (a + b)
            high = albedo_of(m) > target
            b = np.where(high, m, b)
            a = np.where(high, a, m)
        return 0.5 * (a + b)

    interfaces = [{"type": "dielectric", "ior": round(n_eff, 6), "roughness": round(coat["roughness"] ** 2, 6),
                   "distribution": dist}]
    if base_kind == "plastic":
        itf = interface(eta_l, rough)
        spec_in, trans_in = itf["R"][inside].mean(), itf["T"][inside].mean()
        r_diffuse, t_diffuse = itf["R"].mean(), itf["T"].mean()

        # The base's own reflection leaves through the coat like the light came in (a smooth
        # base) or spread like diffuse light (a rough one); in between, a blend fitted to
        # Lamina's layered BSDF (tests/test_principled_table.py checks the result).
        s_exit = float(np.clip(1.0 - 1.5 * rough, 0.0, 1.0))
        spec_exit = s_exit * Tc + (1.0 - s_exit) * top["Td"]

        def parts(rho):
            K = rho * itf["Td"] / (1.0 - rho * itf["Rd"])
            body = trans_in * K                                  # leaves the base diffusely
            b_diffuse = r_diffuse + t_diffuse * K                # the base under diffuse light
            return K, body, b_diffuse

        def albedo_of(rho):
            _, body, b_diffuse = parts(rho)
            return Rc + Tc * (spec_in * spec_exit + body * top["Td"]) / (1.0 - top["Rd"] * b_diffuse)

        # Largest body albedo whose light loops (inside the base, and between base and coat)
        # stay below MAX_LOOP_GAIN: beyond it the walk's throughput would not converge.
        grid = np.linspace(0.0, MAX_LOOP_GAIN / max(itf["Rd"], 1e-9), 400)
        ok = [g for g in grid if top["Rd"] * parts(g)[2] < MAX_LOOP_GAIN]
        limit = float(ok[-1]) if ok else 0.0
        rho = solve(albedo_of, 0.0, limit)
        clamped = bool(np.any(albedo_of(np.zeros(3)) > target + 1e-4) or np.any(albedo_of(np.full(3, limit)) < target - 1e-4))
        interfaces += [{"type": "dielectric", "ior": round(n_eff * eta_l, 6), "roughness": round(alpha, 6),
                        "distribution": dist}, {"type": "diffuse", "color": _rgb(rho)}]
        media = [{"thickness": 1.0, "sigma_t": 0.0}, {"thickness": 1.0, "sigma_t": 0.0}]
    else:
        t = table()
        b = int(t["bins"])
        centres = (np.arange(b) + 0.5) / b                          # bin centres in cos²θ
        mu2_in = 1.0 - (1.0 - centres) / n_eff ** 2                  # each outside bin, refracted
        curves = np.array([lookup("lamina_conductor", f, rough, "f0") for f in t["f0"]])   # (F, B)
        m_in_f = np.array([np.interp(mu2_in, centres, c) for c in curves])                 # (F, B)
        m_all_f = curves.mean(axis=1)
        # A metal reflects (mostly) specularly: a smooth one sends the light back out the way it
        # came (per viewing bin: in through the coat at that bin's refracted angle, out again), a
        # rough one spreads it like diffuse light inside the coat; the blend is fitted to
        # Lamina's layered BSDF (tests/test_principled_table.py checks three roughnesses).
        s_exit = float(np.clip(1.0 - METAL_SPREAD * rough, 0.0, 1.0))
        exit_ = s_exit * top["T"] + (1.0 - s_exit) * top["Td"]        # (B,)
        back = s_exit * Rc + (1.0 - s_exit) * top["Rd"]

        def albedo_of(f0):
            out = np.empty(3)
            for c in range(3):
                m_in = np.array([np.interp(f0[c], t["f0"], m_in_f[:, k]) for k in range(b)])
                m_all = np.interp(f0[c], t["f0"], m_all_f)
                out[c] = np.mean(top["R"] + top["T"] * m_in * exit_ / (1.0 - back * m_all))
            return out

        f0 = solve(albedo_of, 0.0, 1.0)
        clamped = bool(np.any(albedo_of(np.zeros(3)) > target + 1e-4) or np.any(albedo_of(np.ones(3)) < target - 1e-4))
        interfaces.append(_conductor(f0, alpha, dist, n_eff))
        media = [{"thickness": 1.0, "sigma_t": 0.0}]
    return {"type": "layered", "interfaces": interfaces, "media": media}, clamped
