"""What the agreement check catches: Cycles references rendered with one deliberate conversion
mistake each, compared region by region with Lamina's (cached) reference.

    python -m benchmarks.peers.sensitivity [--quick]

Not part of the report (it re-renders Cycles references: about a minute of CPU). The mistakes are
the ones the converter has to get right and a reader could doubt:

* ``filter``    — Cycles' ``filter_width`` twice the scene's (3 instead of 1.5: the mistake this
  benchmark found in Lamina's own filter);
* ``multiscatter`` — Cycles' default Multiscatter GGX instead of plain GGX;
* ``r = α``     — Lamina's α passed as Cycles' roughness slider (Cycles squares it).

Each row says how many regions fail and the largest |z|; the correct conversion (``none``) is
listed for comparison.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from . import agree, convert
from .cycles_process import CyclesProcess
from .run import REF_SPLIT, lamina_reference
from .scenes import PEER_SCENES

CASES = [("cornell", "none", {}), ("cornell", "filter", {"filter_width": 3.0}),
         ("furnace", "none", {}), ("furnace", "multiscatter", {"distribution": "MULTI_GGX"}),
         ("grazing", "none", {}), ("grazing", "r = α", {"roughness_is_alpha": True})]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.peers.sensitivity", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--cache", type=Path, default=Path(__file__).resolve().parent.parent / ".cache")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    log = lambda m: print(f"[{time.perf_counter() - t0:6.1f} s] {m}", flush=True)  # noqa: E731
    scenes = {s.name: s for s in PEER_SCENES}
    rows = []
    with CyclesProcess() as cy:
        for name, label, overrides in CASES:
            sc = scenes[name]
            size, ref_spp = (sc.quick_size, sc.quick_ref_spp) if args.quick else (sc.size, sc.ref_spp)
            data = sc.build(size)
            lam = lamina_reference(data, name, ref_spp, args.cache, log)
            job = convert.prepare(data, args.cache / "peers-jobs" / f"{name}-sensitivity", overrides, sc.principled)
            cy.build(job, 2)
            imgs = [cy.render(ref_spp // REF_SPLIT, 9_000_001 + k)[0] for k in range(REF_SPLIT)]
            img, var = agree.split_variance(imgs)
            from backend.scene.loader import load_scene_data
            soup = load_scene_data(data).soup
            lab, names = agree.labels(data, soup.vertices, soup.object_id)
            v = agree.verdict(agree.check(lam["image"], lam["var"], img, var, agree.regions(lab, names)))
            rows.append((name, label, v))
            log(f"{name:8s} {label:13s} {v['failed']:3d}/{v['regions']} regions fail, max |z| {v['max_abs_z']:.1f}: "
                f"{', '.join(v['failed_names'][:4])}{' …' if v['failed'] > 4 else ''}")
    print("\n| scene | Cycles conversion | regions failing | largest \\|z\\| |\n|---|---|---|---|")
    for name, label, v in rows:
        print(f"| {name} | {label} | {v['failed']} / {v['regions']} | {v['max_abs_z']:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
