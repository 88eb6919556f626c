"""Regenerate ``addon/export/principled_table.json``: what the add-on needs to give a Principled
BSDF the same directional albedo in Lamina as in Cycles (docs/blender.md, "Principled BSDF").

    .venv/bin/python tools/gen_principled_table.py [--quick] [-o PATH]

Two halves, both tabulated over the same angle bins (the eight bins of equal width in cos²θ of the
viewing direction, so the plain mean of the eight values is the cosine-weighted hemispherical
average, the albedo of the surface under uniform light):

* **Cycles, measured** (the bpy module, Cycles on the CPU): a smooth UV sphere (128 × 64 faces, 96 × 96 pixels, 64 samples)
  under a uniform white world of strength 1, seen by an orthographic camera, no other geometry,
  ``max_bounces = 0``, a transparent film and a 0.01-pixel filter. A convex object's upper
  hemisphere sees only the world, so each pixel is the directional albedo at that pixel's viewing
  angle θ (cos θ = √(1 − x² − y²) on the unit disk); premultiplied pixels are summed per bin and
  divided by their alpha. One render holds three settings, one per RGB channel (base colour or
  Specular Tint per channel). Measured: the Principled specular layer (base colour black), the
  same with Specular Tint 0 (the part the tint does not scale), the metallic layer (F82,
  Specular Tint white) and the sheen layer; the coat layer alone (IOR 1 switches the base
  specular off) equals the specular layer (checked on one row, printed).
* **Lamina, computed** with Lamina's own BSDF code (``backend/materials``): the rough dielectric
  interface's reflectance R and transmittance T from above per bin, and its cosine-weighted
  transmittance and reflectance from below (T↓, R↓); the conductor with η = 1 and k from F0 (the
  add-on's Glossy/Metallic/Principled metal) per bin. A stack "dielectric over Lambertian ρ" then
  has the albedo R + T·K with K = ρT↓/(1 − ρR↓), exactly (the Lambertian base forgets where its
  light came from), which ``tests/test_principled_table.py`` checks against the layered BSDF.

The add-on (``addon/export/principled.py``) only interpolates these tables and combines them with
Cycles' own layering rules; it runs no BSDF. Cost: about ten minutes on two cores.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

BINS = 8
EDGES_MU2 = np.linspace(0.0, 1.0, BINS + 1)                 # bins equal in cos²θ
MU = np.sqrt(0.5 * (EDGES_MU2[:-1] + EDGES_MU2[1:]))        # a representative cos θ per bin
IOR = [1.05, 1.1, 1.2, 1.3, 1.4, 1.45, 1.5, 1.6, 1.7, 1.8, 2.0, 2.4, 3.0, 4.0, 6.0]
ROUGHNESS = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
F0 = [0.0, 0.04, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
SHEEN_ROUGHNESS = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
OUT = ROOT / "addon" / "export" / "principled_table.json"


# --------------------------------------------------------------------------- Lamina (no bpy)

def _material(doc: dict):
    from backend.materials import load_all
    from backend.scene.reader import LoadContext, Node, dispatch
    ctx = LoadContext("<principled table>")
    ctx.cache["layered_defaults"] = {}
    return dispatch(Node(doc, "", ctx), load_all())


def _forward(material, wi: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """Per-lane reflected and transmitted sample weights (importance transport) for directions wi."""
    from backend.materials.base import IMPORTANCE, ShadingContext
    b = material.bind(ShadingContext(np.full((wi.shape[0], 2), 0.5)))
    s = b.sample(wi, rng, IMPORTANCE)
    w = np.where(np.isfinite(s.weight), s.weight, 0.0)
    same = (s.wo[:, 2] * wi[:, 2]) > 0
    return w * same[:, None], w * ~same[:, None]


def _directions(mu2: np.ndarray, below: bool = False) -> np.ndarray:
    mu = np.sqrt(np.clip(mu2, 1e-8, 1.0))
    wi = np.stack([np.sqrt(1.0 - mu * mu), np.zeros_like(mu), -mu if below else mu], axis=1)
    return wi


def lamina_binned(material, samples: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """R and T (bins, 3) from above, each bin's directions uniform in cos²θ (exact bin means)."""
    R = np.empty((BINS, 3))
    T = np.empty((BINS, 3))
    for k in range(BINS):
        mu2 = EDGES_MU2[k] + (EDGES_MU2[k + 1] - EDGES_MU2[k]) * rng.random(samples)
        r, t = _forward(material, _directions(mu2), rng)
        R[k], T[k] = r.mean(axis=0), t.mean(axis=0)
    return R, T


def lamina_tables(samples: int, seed: int = 1) -> dict:
    from addon.util import f0_to_conductor_k          # bpy-free helper shared with the export
    rng = np.random.default_rng(seed)
    shape = (len(IOR), len(ROUGHNESS))
    R = np.zeros(shape + (BINS,))
    T = np.zeros(shape + (BINS,))
    Rd = np.zeros(shape)
    Td = np.zeros(shape)
    for i, ior in enumerate(IOR):
        for j, r in enumerate(ROUGHNESS):
            mat = _material({"type": "dielectric", "ior": ior, "roughness": r * r})
            Rb, Tb = lamina_binned(mat, samples, rng)
            R[i, j], T[i, j] = Rb[:, 0], Tb[:, 0]
            # From below, cosine-weighted (cos²θ uniform): the light a Lambertian base sends up.
            rd, td = _forward(mat, _directions(rng.random(samples * 2), below=True), rng)
            Rd[i, j], Td[i, j] = rd[:, 0].mean(), td[:, 0].mean()
    C = np.zeros((len(F0), len(ROUGHNESS), BINS))
    for i, f0 in enumerate(F0):
        for j, r in enumerate(ROUGHNESS):
            k = f0_to_conductor_k([f0])[0]
            mat = _material({"type": "conductor", "eta": [1.0] * 3, "k": [k] * 3, "roughness": r * r})
            C[i, j] = lamina_binned(mat, samples, rng)[0][:, 0]
    return {"lamina_R": R, "lamina_T": T, "lamina_R_down": Rd, "lamina_T_down": Td, "lamina_conductor": C}


# --------------------------------------------------------------------------- Cycles (bpy)

class Furnace:
    def __init__(self, res: int, spp: int, threads: int, folder: Path):
        import bpy
        self.bpy = bpy
        self.res, self.spp, self.folder = res, spp, folder
        bpy.ops.wm.read_factory_settings(use_empty=True)
        sc = self.scene = bpy.context.scene
        sc.render.engine = "CYCLES"
        cy = sc.cycles
        cy.device = "CPU"
        cy.use_denoising = False
        cy.use_adaptive_sampling = False
        cy.max_bounces = 0
        cy.sample_clamp_direct = cy.sample_clamp_indirect = 0.0
        cy.filter_width = 0.01
        cy.samples = spp
        sc.render.resolution_x = sc.render.resolution_y = res
        sc.render.resolution_percentage = 100
        sc.render.film_transparent = True
        sc.render.threads_mode = "FIXED"
        sc.render.threads = threads
        sc.render.image_settings.file_format = "OPEN_EXR"
        sc.render.image_settings.color_depth = "32"
        sc.view_settings.view_transform = "Standard"
        world = bpy.data.worlds.new("furnace")
        sc.world = world
        bg = world.node_tree.nodes["Background"]
        bg.inputs["Color"].default_value = (1, 1, 1, 1)
        bg.inputs["Strength"].default_value = 1.0
        bpy.ops.mesh.primitive_uv_sphere_add(segments=128, ring_count=64, radius=1.0)
        obj = bpy.context.active_object
        bpy.ops.object.shade_smooth()
        self.scale = 2.05
        cam = bpy.data.cameras.new("cam")
        cam.type = "ORTHO"
        cam.ortho_scale = self.scale
        co = bpy.data.objects.new("cam", cam)
        co.location = (0.0, 0.0, 5.0)
        sc.collection.objects.link(co)
        sc.camera = co
        self.material = bpy.data.materials.new("principled")
        obj.data.materials.append(self.material)
        self.node = self.material.node_tree.nodes["Principled BSDF"]
        # Bin index per pixel from its centre (pixels beyond the rim belong to the last bin).
        c = ((np.arange(res) + 0.5) / res * 2.0 - 1.0) * self.scale / 2.0
        x, y = np.meshgrid(c, c)
        mu2 = np.clip(1.0 - x * x - y * y, 0.0, 1.0)
        self.bin = np.minimum((mu2 * BINS).astype(int), BINS - 1)

    def set(self, **inputs) -> None:
        defaults = {"Base Color": (0, 0, 0, 1), "Metallic": 0.0, "Roughness": 0.5, "IOR": 1.5,
                    "Specular IOR Level": 0.5, "Specular Tint": (1, 1, 1, 1), "Coat Weight": 0.0,
                    "Coat Roughness": 0.03, "Coat IOR": 1.5, "Coat Tint": (1, 1, 1, 1),
                    "Sheen Weight": 0.0, "Sheen Roughness": 0.5, "Sheen Tint": (1, 1, 1, 1),
                    "Transmission Weight": 0.0}
        defaults.update(inputs)
        for name, value in defaults.items():
            self.node.inputs[name].default_value = value

    def render(self) -> np.ndarray:
        """(BINS, 3) directional albedo per bin and channel."""
        import OpenImageIO as oiio
        path = self.folder / "furnace.exr"
        self.scene.render.filepath = str(path)
        self.bpy.ops.render.render(write_still=True)
        inp = oiio.ImageInput.open(str(path))
        px = np.asarray(inp.read_image(0, 0, 0, 4, oiio.FLOAT), dtype=np.float64)
        inp.close()
        px = px.reshape(self.res, self.res, 4)
        out = np.zeros((BINS, 3))
        for k in range(BINS):
            sel = self.bin == k
            out[k] = px[..., :3][sel].sum(axis=0) / max(px[..., 3][sel].sum(), 1e-12)
        return out


def cycles_tables(res: int, spp: int, threads: int, folder: Path) -> dict:
    f = Furnace(res, spp, threads, folder)
    shape = (len(IOR), len(ROUGHNESS), BINS)
    spec, edge, half = (np.zeros(shape) for _ in range(3))
    for i, ior in enumerate(IOR):
        for j, r in enumerate(ROUGHNESS):
            # Specular Tint per channel: 1 (the layer), 0 (the part the tint does not scale), ½ (a check).
            f.set(**{"IOR": ior, "Roughness": r, "Specular Tint": (1.0, 0.0, 0.5, 1.0)})
            a = f.render()
            spec[i, j], edge[i, j], half[i, j] = a[:, 0], a[:, 1], a[:, 2]
        print(f"  Cycles IOR {ior}: done", flush=True)
    # The coat layer alone (IOR 1 switches the base specular off) on one row: Cycles' coat is the
    # same dielectric GGX lobe as the specular layer, so the specular table serves both.
    i = IOR.index(1.5)
    coat = np.array([(f.set(**{"IOR": 1.0, "Coat Weight": 1.0, "Coat IOR": 1.5, "Coat Roughness": r}),
                      f.render()[:, 0])[1] for r in ROUGHNESS])
    coat_error = float(np.max(np.abs(coat - spec[i])))
    print(f"  coat layer vs specular layer (IOR 1.5): max |difference| {coat_error:.4f}")
    metal = np.zeros((len(F0), len(ROUGHNESS), BINS))
    for j, r in enumerate(ROUGHNESS):
        for s in range(0, len(F0), 3):
            group = F0[s:s + 3] + [0.0] * (3 - len(F0[s:s + 3]))
            f.set(**{"Metallic": 1.0, "Roughness": r, "Base Color": (*group, 1.0)})
            a = f.render()
            for c, k in enumerate(range(s, min(s + 3, len(F0)))):
                metal[k, j] = a[:, c]
    sheen = np.zeros((len(SHEEN_ROUGHNESS), BINS))
    for j, r in enumerate(SHEEN_ROUGHNESS):
        f.set(**{"IOR": 1.0, "Sheen Weight": 1.0, "Sheen Roughness": r})
        sheen[j] = f.render()[:, 0]
    half_error = float(np.max(np.abs(half - 0.5 * (spec + edge))))
    print(f"  Specular Tint ½ vs the mean of tints 1 and 0: max |difference| {half_error:.4f}")
    return {"cycles_specular": spec, "cycles_specular_untinted_part": edge,
            "cycles_metal": metal, "cycles_sheen": sheen, "specular_tint_linearity_error": half_error,
            "coat_vs_specular_error": coat_error}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", default=str(OUT))
    ap.add_argument("--quick", action="store_true", help="fewer samples (for trying the tool out)")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args(argv)
    import tempfile
    t0 = time.perf_counter()
    samples = 4000 if args.quick else 40000
    res, spp = (48, 32) if args.quick else (96, 64)
    with tempfile.TemporaryDirectory(prefix="lamina-principled-") as tmp:
        cyc = cycles_tables(res, spp, args.threads, Path(tmp))
    t1 = time.perf_counter()
    lam = lamina_tables(samples)
    t2 = time.perf_counter()

    def rounded(a):
        return np.round(np.asarray(a, dtype=np.float64), 5).tolist()

    doc = {"format": "lamina-principled-table", "version": 1,
           "generator": "tools/gen_principled_table.py",
           "method": {"cycles": f"bpy Cycles furnace sphere, {res}x{res} px, {spp} spp",
                      "lamina": f"backend/materials BSDF sampling, {samples} samples per bin"},
           "bins": BINS, "mu": rounded(MU), "ior": IOR, "roughness": ROUGHNESS, "f0": F0,
           "sheen_roughness": SHEEN_ROUGHNESS,
           "specular_tint_linearity_error": round(cyc.pop("specular_tint_linearity_error"), 5),
           "coat_vs_specular_error": round(cyc.pop("coat_vs_specular_error"), 5)}
    for key, value in {**cyc, **lam}.items():
        doc[key] = rounded(value)
    Path(args.output).write_text(json.dumps(doc, separators=(",", ":")) + "\n")
    print(f"wrote {args.output}: Cycles {t1 - t0:.0f} s, Lamina {t2 - t1:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
