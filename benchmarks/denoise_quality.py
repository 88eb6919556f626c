"""How much closer to the converged image denoising brings a preview render (issue 38).

    .venv/bin/python -m benchmarks.denoise_quality [--scene demo/demo.json] [--resolution WxH]
        [--spp 32] [--reference-spp 4096] [--seeds 1]

Renders the scene at ``--spp`` with ``render --denoise`` (the CLI's route: pyoidn, fed with the
film's albedo and normal), and once at ``--reference-spp`` (cached in benchmarks/.cache/). The
32-spp render's own image (the EXR's ``noisy`` layer) is then also denoised by the route F12
takes in Blender — addon/engine/denoise.py, the OIDN inside Blender's Cycles — in a bpy child
process, from the same pixels. Prints each image's RMSE against the reference, raw and with the
reference's own noise taken out (its per-pixel variance of the mean, from the EXR), and the
ratio denoised / noisy. The acceptance asks for ≤ 0.25 on the demo at 32 spp. The resolution
is the scene's own unless given. With ``--seeds N`` the 32-spp render is repeated with seeds
0 … N−1 (the reference stays), and the ratios of each and their mean are printed: a few bright
pixels can hold most of the error, so one seed's ratio is itself a noisy figure.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
CACHE = REPO / "benchmarks" / ".cache"

_BLENDER_CHILD = r"""
import sys, json
import numpy as np
import bpy
sys.path.insert(0, sys.argv[1])
import importlib.util
spec = importlib.util.spec_from_file_location("lamina_denoise", sys.argv[1] + "/addon/engine/denoise.py")
module = importlib.util.module_from_spec(spec); spec.loader.exec_module(module)
data = np.load(sys.argv[2])
out = module.denoise_image(data["combined"], data["aovs"], int(sys.argv[4]), sys.argv[5], bpy.context.scene,
                           bpy.context.view_layer, bpy.context.preferences)
np.save(sys.argv[3], out)
"""


def _render(scene: str, out: Path, spp: int, resolution: str, *extra: str) -> None:
    cmd = [sys.executable, "-m", "backend", "render", scene, "-o", str(out), "--spp", str(spp),
           "--resolution", resolution, "--progress", "none", *extra]
    print("  " + " ".join(cmd[1:]), flush=True)
    subprocess.run(cmd, cwd=REPO, check=True)


def _layer(pixels: np.ndarray, names: list[str], layer: str, letters: str = "RGB") -> np.ndarray:
    prefix = f"{layer}." if layer else ""
    return pixels[:, :, [names.index(f"{prefix}{c}") for c in letters]]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="demo/demo.json")
    ap.add_argument("--resolution", default=None, help="WxH (default: the scene's own)")
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--reference-spp", type=int, default=4096)
    ap.add_argument("--seeds", type=int, default=1, help="repeat the render with seeds 0 … N−1")
    args = ap.parse_args(argv)
    from backend.imageio import read_exr
    if args.resolution is None:
        film = json.loads((REPO / args.scene).read_text()).get("film", {})
        args.resolution = f"{film.get('width', 640)}x{film.get('height', 480)}"
    CACHE.mkdir(parents=True, exist_ok=True)
    stem = Path(args.scene).stem
    reference_path = CACHE / f"denoise-ref-{stem}-{args.resolution}-{args.reference_spp}.exr"
    if not reference_path.exists():
        print(f"reference ({args.reference_spp} spp, cached afterwards):", flush=True)
        _render(args.scene, reference_path, args.reference_spp, args.resolution)
    ref_pixels, ref_names = read_exr(reference_path)
    reference = _layer(ref_pixels, ref_names, "")
    ref_var = float(np.mean(_layer(ref_pixels, ref_names, "variance")))
    runs = [_measure(args, reference, ref_var, seed) for seed in (range(args.seeds) if args.seeds > 1 else [None])]
    if len(runs) > 1:
        print(f"\nratios to the noisy image over {len(runs)} seeds (without the reference's noise):")
        for label in runs[0]:
            ratios = [r[label]["rmse_without_reference_noise"] / r["noisy (as rendered)"]["rmse_without_reference_noise"]
                      for r in runs if label in r]
            print(f"  {label:52s} " + " ".join(f"{x:.3f}" for x in ratios) + f"   mean {np.mean(ratios):.3f}")
    return 0


def _measure(args, reference: np.ndarray, ref_var: float, seed) -> dict:
    """One render at ``args.spp`` (with ``seed``, or the scene's), denoised both ways; the RMSE rows."""
    from backend.imageio import read_exr
    work = Path(tempfile.mkdtemp(prefix="lamina-denoise-"))
    _render(args.scene, work / "render.exr", args.spp, args.resolution, "--denoise",
            *(["--seed", str(seed)] if seed is not None else []))
    pixels, names = read_exr(work / "render.exr")
    images = {"noisy (as rendered)": _layer(pixels, names, "noisy")}
    if "noisy.R" in names:
        images["denoised: render --denoise (pyoidn)"] = _layer(pixels, names, "")
    else:
        images = {"noisy (as rendered)": _layer(pixels, names, "")}
        print("  render --denoise did not denoise (pyoidn missing?)")
    # Blender's route, from the same noisy pixels and features.
    combined = np.concatenate([images["noisy (as rendered)"], _layer(pixels, names, "", "A")], axis=2)
    aovs = np.concatenate([_layer(pixels, names, "albedo"), _layer(pixels, names, "normal", "XYZ")], axis=2)
    np.savez(work / "features.npz", combined=combined, aovs=aovs)
    child = subprocess.run([sys.executable, "-c", _BLENDER_CHILD, str(REPO), str(work / "features.npz"),
                            str(work / "blender.npy"), str(args.spp), str(work)],
                           capture_output=True, text=True, cwd=work)
    if child.returncode == 0:
        images["denoised: F12's route (OIDN in Blender's Cycles)"] = np.load(work / "blender.npy")[:, :, :3]
    else:
        print(f"  Blender's route failed or bpy is missing: {child.stderr.strip().splitlines()[-1:]}")
    print(f"\n{args.scene} at {args.resolution}, {args.spp} spp{'' if seed is None else f', seed {seed}'}; "
          f"reference {args.reference_spp} spp (its own noise: mean variance {ref_var:.3g}, subtracted below)")
    base = None
    rows = {}
    for label, image in images.items():
        mse = float(np.mean((image - reference) ** 2))
        corrected = max(mse - ref_var, 0.0)
        rmse, rmse_c = mse ** 0.5, corrected ** 0.5
        base = base or (rmse, rmse_c)
        rows[label] = {"rmse": rmse, "rmse_without_reference_noise": rmse_c}
        print(f"  {label:52s} RMSE {rmse:.5f} ({rmse / base[0]:.3f}×)   without the reference's noise "
              f"{rmse_c:.5f} ({rmse_c / max(base[1], 1e-30):.3f}×)")
    print(json.dumps(rows))
    return rows


if __name__ == "__main__":
    sys.exit(main())
