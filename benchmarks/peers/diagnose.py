"""Where does a renderer's error come from? Per-region variance of Lamina and Cycles at equal spp.

    python -m benchmarks.peers.diagnose cornell --spp 16 --seeds 8 [--bounces 8,1,0] [--lamina-only]

For each variant (max_bounces; Lamina's sampler), ``--seeds`` independent renders of each
renderer give the per-pixel variance of one render (sample variance across the seeds, ddof 1):
for an unbiased renderer that *is* its MSE, so no reference is needed. The table gives, per
region of the agreement check (``agree.labels``, whole labels, not tiles), the region's share of
the image's total variance for each renderer and the ratio Lamina / Cycles of the region's summed
variance (> 1: Lamina noisier there). ``--save`` writes the variance maps (npz) for a look.
"""
from __future__ import annotations

import argparse
import copy
import os
import sys
from pathlib import Path

import numpy as np

from ..measure import render
from . import agree, convert
from .cycles_process import CyclesProcess
from .scenes import PEER_SCENES


def _variance(images: list[np.ndarray]) -> np.ndarray:
    """Per-pixel variance of one render (sum over RGB), from independent renders."""
    s = np.stack(images)
    return s.var(axis=0, ddof=1).sum(axis=-1)


def _labels(data: dict):
    from backend.scene.loader import load_scene_data
    scene = load_scene_data(copy.deepcopy(data), "<diagnose>")
    lab, names = agree.labels(data, scene.soup.vertices, scene.soup.object_id)
    return lab, names


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--seed-base", type=int, default=5000, help="Lamina's seeds are seed-base + k (another set: another base)")
    ap.add_argument("--bounces", default="8")
    ap.add_argument("--size", type=int, default=0)
    ap.add_argument("--lamina-only", action="store_true")
    ap.add_argument("--samplers", default="sobol")
    ap.add_argument("--patch", default="", help="JSON deep-merged into Lamina's scene dict only")
    ap.add_argument("--save", type=Path)
    ap.add_argument("--both-patch", default="", help="JSON deep-merged into the scene dict of both renderers")
    ap.add_argument("--lights", default="", help="keep only these light indices (both renderers)")
    ap.add_argument("--means", action="store_true", help="also the agreement check of the seeds' means (per tile)")
    ap.add_argument("--rr-depth", type=int, default=0, help="both renderers' roulette depth (0: the scene's)")
    ap.add_argument("--strat", type=int, default=0, help="override integrator.STRATIFIED_BOUNCES (threads only)")
    args = ap.parse_args(argv)
    if args.strat:
        from backend import integrator
        integrator.STRATIFIED_BOUNCES = args.strat
    sc = {s.name: s for s in PEER_SCENES}[args.scene]
    size = args.size or sc.size
    base = sc.build(size)
    if args.both_patch:
        import json

        from ..measure import apply_patch
        patch = json.loads(args.both_patch)
        base = apply_patch(base, {k: v for k, v in patch.items() if k != "materials"})
        base["materials"].update(patch.get("materials", {}))      # materials replaced whole
    if args.lights:
        base["lights"] = [base["lights"][int(i)] for i in args.lights.split(",")]
    lab, names = _labels(base)
    groups = [(n, lab == i) for i, n in enumerate(names) if (lab == i).any()]
    cache = Path(__file__).resolve().parent.parent / ".cache" / "diagnose"
    cy = None if args.lamina_only else CyclesProcess()
    saved = {"labels": lab, "names": np.array(names)}
    try:
        for nb in [int(b) for b in args.bounces.split(",")]:
            data = copy.deepcopy(base)
            data["render"]["max_bounces"] = nb
            if args.rr_depth:
                data["render"]["rr_depth"] = args.rr_depth
            var = {}
            for smp in args.samplers.split(","):
                d = copy.deepcopy(data)
                d["render"]["sampler"] = smp
                if args.patch:
                    import json

                    from ..measure import apply_patch
                    d = apply_patch(d, json.loads(args.patch))
                runs = [render(d, args.spp, args.seed_base + k, os.cpu_count() or 1, "diag") for k in range(args.seeds)]
                imgs = [r.image for r in runs]
                means = {"lamina": imgs}
                print(f"lamina/{smp}: CPU per render {np.median([r.cpu for r in runs]):.3f} s (median of {len(runs)})")
                var[f"lamina/{smp}"] = _variance(imgs)
            if cy is not None:
                job = convert.prepare(data, cache / f"{args.scene}-{nb}", principled=sc.principled)
                cy.build(job, os.cpu_count() or 1)
                imgs = [cy.render(args.spp, 9000 + k)[0] for k in range(args.seeds)]
                var["cycles"] = _variance(imgs)
                if args.means:
                    la, lv = agree.split_variance(means["lamina"])
                    ca, cv = agree.split_variance(imgs)
                    for r in agree.check(la, lv, ca, cv, agree.regions(lab, names)):
                        if r.name.startswith(("whole", "back wall [t")) or not r.ok:
                            print(f"  {r.name[:24]:24s} Lamina/Cycles − 1 (RGB) "
                                  + " ".join(f"{x * 100:+6.2f}%" for x in r.rel_diff)
                                  + "  z " + " ".join(f"{x:+5.2f}" for x in r.z))
            for k, v in var.items():
                saved[f"{k}/{nb}"] = v
            keys = list(var)
            print(f"\n## {args.scene} {size}², max_bounces {nb}, {args.spp} spp, {args.seeds} seeds: "
                  "per-region share of the total variance, and ratios to Cycles")
            print(f"{'region':22s} {'px':>5s} " + " ".join(f"{k:>16s}" for k in keys)
                  + ("  " + " ".join(f"{k + '/cy':>16s}" for k in keys if k != "cycles") if "cycles" in var else ""))
            tot = {k: v.sum() for k, v in var.items()}
            rows = [("whole image", np.ones_like(lab, bool))] + groups
            for name, mask in rows:
                line = f"{name[:22]:22s} {int(mask.sum()):5d} "
                line += " ".join(f"{var[k][mask].sum() / tot[k] * 100:15.1f}%" for k in keys)
                if "cycles" in var:
                    line += "  " + " ".join(f"{var[k][mask].sum() / max(var['cycles'][mask].sum(), 1e-30):16.2f}"
                                            for k in keys if k != "cycles")
                print(line)
            print("total variance (sum over pixels): " + ", ".join(f"{k} {tot[k]:.4g}" for k in keys))
            sys.stdout.flush()
    finally:
        if cy is not None:
            cy.close()
    if args.save:
        np.savez_compressed(args.save, **saved)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
