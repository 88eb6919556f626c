"""The measurement: references of both renderers, then interleaved timed series.

Per scene:

1. The scene dict (``scenes.py``) is converted once (``convert.prepare``, with the scene's
   Principled materials for Cycles, ``PeerScene.principled``) and built in the bpy child. Both
   renderers get the same sample counts.
2. References: Lamina's from ``benchmarks.measure.reference`` (cached, keyed by the scene and a
   hash of backend/); Cycles' as ``REF_SPLIT`` independent renders of ref_spp / REF_SPLIT samples
   (mean, and per-pixel variance of the mean from their spread), cached keyed by the job, the
   converter's source and the Blender version.
3. Series: for each repeat and sample count, one Lamina render and one Cycles render back to
   back, the order alternating from pair to pair (A B, B A, ...), with independent seeds. CPU time
   is the primary clock: Lamina's = this process + its worker processes (``getrusage`` self +
   children), Cycles' = the bpy child's own ``getrusage`` over its render call (its render threads
   included). During each render the rest of the machine's CPU use is measured from /proc/stat
   (busy time of all cores minus the render's own CPU time); when that background load differs by
   more than ``LOAD_MOVED`` cores between the two renders of a pair, the pair is rendered again
   (up to ``MAX_RETRIES`` times) and the pair with the smallest difference is kept. /proc/stat
   counts in 10 ms ticks, so renders shorter than ``MIN_LOAD_WINDOW`` are too short to tell and
   are never repeated (their load is still recorded).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..measure import reference, render
from . import agree, convert, metrics, startup
from .cycles_process import CyclesProcess
from .scenes import PeerScene

HERE = Path(__file__).resolve().parent
REF_SPLIT = 16           # Cycles reference = this many independent renders (variance from their spread)
LOAD_MOVED = 0.5         # cores of background load difference that makes a pair run again
MAX_RETRIES = 2
MIN_LOAD_WINDOW = 0.5    # seconds of wall time below which a render's background load is too coarse
REPEATS = 2              # series repeats (full run)
SEED_L, SEED_C = 1000, 2000


# --------------------------------------------------------------------------- machine load

def _busy_seconds() -> float:
    """CPU seconds all cores have been busy since boot (/proc/stat; 0 where unavailable)."""
    try:
        with open("/proc/stat", encoding="ascii") as f:
            parts = f.readline().split()[1:]
    except OSError:
        return 0.0
    v = [int(x) for x in parts]
    idle = v[3] + (v[4] if len(v) > 4 else 0)             # idle + iowait
    return (sum(v[:8]) - idle) / os.sysconf("SC_CLK_TCK")


class LoadMeter:
    """Background load during one render, in cores: (machine busy − own CPU) / wall."""

    def __enter__(self):
        self.b0, self.t0 = _busy_seconds(), time.perf_counter()
        return self

    def finish(self, own_cpu: float) -> float:
        wall = time.perf_counter() - self.t0
        other = _busy_seconds() - self.b0 - own_cpu
        return max(other, 0.0) / max(wall, 1e-6)

    def __exit__(self, *exc):
        return False


# --------------------------------------------------------------------------- references

def _source_digest(*files: Path) -> str:
    h = hashlib.sha256()
    for f in files:
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


def cycles_reference(cy: CyclesProcess, job_dir: Path, name: str, spp: int, cache: Path, log) -> dict:
    h = hashlib.sha256()
    h.update((job_dir / "job.json").read_bytes())
    h.update((job_dir / "geometry.npz").read_bytes())
    for light in json.loads((job_dir / "job.json").read_text(encoding="utf-8")).get("lights", []):
        if "ies" in light:
            h.update(Path(light["ies"]["file"]).read_bytes())
    h.update(f"{spp}/{REF_SPLIT}/{cy.version}/{os.cpu_count()}".encode())
    h.update(_source_digest(HERE / "to_cycles.py", HERE / "cycles_child.py").encode())
    path = cache / f"peers-cycles-{name}-{h.hexdigest()[:20]}.npz"
    if path.exists():
        z = np.load(path, allow_pickle=False)
        return {"image": z["image"], "var": z["var"], "cpu": float(z["cpu"]), "wall": float(z["wall"]),
                "spp": spp, "cached": True}
    log(f"  rendering the Cycles reference for {name}: {REF_SPLIT} × {spp // REF_SPLIT} spp...")
    imgs, cpu, wall = [], 0.0, 0.0
    for k in range(REF_SPLIT):
        img, c, w = cy.render(spp // REF_SPLIT, 7_000_001 + k)
        imgs.append(img)
        cpu += c
        wall += w
    image, var = agree.split_variance(imgs)
    cache.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, image=image, var=var, cpu=cpu, wall=wall)
    tmp.replace(path)
    return {"image": image, "var": var, "cpu": cpu, "wall": wall, "spp": spp, "cached": False}


def lamina_reference(data: dict, name: str, spp: int, cache: Path, log) -> dict:
    run, cached = reference(data, f"peers-{name}", spp, cache, log)
    return {"image": run.image, "var": run.var, "cpu": run.cpu, "wall": run.wall, "spp": spp, "cached": cached}


# --------------------------------------------------------------------------- one timed render each

def _lamina(data: dict, spp: int, seed: int, workers: int) -> dict:
    with LoadMeter() as lm:
        r = render(data, spp, seed, workers, "peers")
        load = lm.finish(r.cpu)
    return {"renderer": "lamina", "spp": spp, "seed": seed, "cpu": r.cpu, "wall": r.wall, "load": load,
            "image": r.image}


def _cycles(cy: CyclesProcess, spp: int, seed: int) -> dict:
    with LoadMeter() as lm:
        img, cpu, wall = cy.render(spp, seed)
        load = lm.finish(cpu)
    return {"renderer": "cycles", "spp": spp, "seed": seed, "cpu": cpu, "wall": wall, "load": load, "image": img}


@dataclass
class SceneRun:
    scene: PeerScene
    data: dict
    size: int
    build: dict
    refs: dict                       # renderer -> reference dict
    runs: list = field(default_factory=list)
    agreement: list = field(default_factory=list)
    darker: list = field(default_factory=list)
    regions_dropped: list = field(default_factory=list)
    load_avg: tuple = ()
    retries: int = 0
    label_image: np.ndarray | None = None    # (H, W) region labels of the agreement check
    label_names: list = field(default_factory=list)
    startup: dict = field(default_factory=dict)   # Lamina's start-up parts (startup.py)


def measure_scene(cy: CyclesProcess, sc: PeerScene, quick: bool, cache: Path, log, workers: int) -> SceneRun:
    size, spps, ref_spp = (sc.quick_size, sc.quick_spp, sc.quick_ref_spp) if quick else (sc.size, sc.spp, sc.ref_spp)
    repeats = 1 if quick else REPEATS
    data = sc.build(size)
    job_dir = cache / "peers-jobs" / sc.name
    job = convert.prepare(data, job_dir, principled=sc.principled)
    build = cy.build(job, workers)
    load0 = os.getloadavg()[0]
    log(f"  {sc.name}: {size}x{size}, Cycles scene built ({build['info']['triangles']} triangles, "
        f"camera frame error {build['info']['camera_frame_error']:.1e})")
    refs = {"lamina": lamina_reference(data, sc.name, ref_spp, cache, log),
            "cycles": cycles_reference(cy, job_dir, sc.name, ref_spp, cache, log)}
    out = SceneRun(sc, data, size, build, refs)
    _agreement(out)
    out.startup = startup.lamina_startup(data, workers)

    pair = 0
    for rep in range(repeats):
        for i, spp in enumerate(spps):
            seed_l, seed_c = SEED_L + 100 * rep + i, SEED_C + 100 * rep + i
            best = None
            for _ in range(MAX_RETRIES + 1):
                first_lamina = pair % 2 == 0
                a = _lamina(data, spp, seed_l, workers) if first_lamina else _cycles(cy, spp, seed_c)
                b = _cycles(cy, spp, seed_c) if first_lamina else _lamina(data, spp, seed_l, workers)
                short = min(a["wall"], b["wall"]) < MIN_LOAD_WINDOW
                moved = 0.0 if short else abs(a["load"] - b["load"])
                if best is None or moved < best[2]:
                    best = (a, b, moved)
                if moved <= LOAD_MOVED:
                    break
                out.retries += 1
                log(f"    background load moved {a['load']:.2f} → {b['load']:.2f} cores: pair again")
            pair += 1
            for r in best[:2]:
                ref = refs[r["renderer"]]
                r.update(metrics.error(r.pop("image"), ref["image"], ref["var"]))
                r["ref_mean"] = float(ref["image"].mean())
                r["rep"] = rep
                r["load_moved"] = best[2]
                out.runs.append(r)
            la, ca = [r for r in best[:2] if r["renderer"] == "lamina"][0], [r for r in best[:2] if r["renderer"] == "cycles"][0]
            log(f"    {spp:4d} spp  Lamina {la['cpu']:6.2f} s CPU rmse {la['rmse']:.4g} | "
                f"Cycles {ca['cpu']:6.2f} s CPU rmse {ca['rmse']:.4g} | background {la['load']:.2f}/{ca['load']:.2f} cores")
    out.load_avg = (load0, os.getloadavg()[0])
    return out


def _agreement(out: SceneRun) -> None:
    """Region-by-region comparison of the two references (and of a 1 % darker Lamina image)."""
    import copy

    from backend.scene.loader import load_scene_data
    scene = load_scene_data(copy.deepcopy(out.data), "<peers>")
    lab, names = agree.labels(out.data, scene.soup.vertices, scene.soup.object_id)
    regs = agree.regions(lab, names)
    kept = {n for n, _ in regs}
    out.regions_dropped = [n for n in names if not any(k == n or k.startswith(n + " [") for k in kept)]
    L, C = out.refs["lamina"], out.refs["cycles"]
    out.agreement = agree.check(L["image"], L["var"], C["image"], C["var"], regs)
    out.darker = agree.check(0.99 * L["image"], 0.99 ** 2 * L["var"], C["image"], C["var"], regs)
    out.label_image = lab
    out.label_names = names


def summarise(sr: SceneRun) -> dict:
    """Curves, targets and equal-error ratios of one scene.

    Two CPU ratios at equal error: *total* — the interpolated CPU time of whole renders (scene
    load, worker start-up / scene sync and BVH included: what one render costs at this size) —
    and *sampling* — start-up excluded: spp at the target × the fitted marginal CPU per spp, i.e.
    spp ratio × cost-per-sample ratio, which does not depend on the image size."""
    key = "rmse" if sr.scene.same_material else "rel_rmse"
    L = [r for r in sr.runs if r["renderer"] == "lamina"]
    C = [r for r in sr.runs if r["renderer"] == "cycles"]
    cl, cc = metrics.curve(L, key), metrics.curve(C, key)
    pixels = sr.size * sr.size
    costs = {"lamina": metrics.cost(L, pixels), "cycles": metrics.cost(C, pixels)}
    cl_, cc_ = costs["lamina"], costs["cycles"]
    cost_ratio = cl_["us_per_px_sample"] / cc_["us_per_px_sample"]
    # Relative standard error of the ratio (independent fits, first order).
    cost_ratio_rse = math.hypot(cl_["us_per_px_sample_se"] / cl_["us_per_px_sample"],
                                cc_["us_per_px_sample_se"] / cc_["us_per_px_sample"])
    rows = []
    for t in metrics.targets(cl["err"], cc["err"]):
        spp_l, xl = metrics.at_error(cl["spp"], cl["err"], t)
        spp_c, xc = metrics.at_error(cc["spp"], cc["err"], t)
        cpu_l, yl = metrics.at_error(cl["cpu"], cl["err"], t)
        cpu_c, yc = metrics.at_error(cc["cpu"], cc["err"], t)
        rows.append({"target": t, "spp_lamina": spp_l, "spp_cycles": spp_c, "cpu_lamina": cpu_l, "cpu_cycles": cpu_c,
                     "spp_ratio": spp_l / spp_c, "cpu_ratio": cpu_l / cpu_c,
                     "cpu_ratio_sampling": spp_l / spp_c * cost_ratio,
                     "extrapolated": bool(xl or xc or yl or yc)})
    good = [r for r in rows if math.isfinite(r["cpu_ratio"]) and r["cpu_ratio"] > 0]

    def geo(k):
        vals = [r[k] for r in good if math.isfinite(r[k]) and r[k] > 0]
        return float(np.exp(np.mean(np.log(vals)))) if vals else float("nan")

    # Only renders long enough for /proc/stat's 10 ms ticks say anything about the load.
    long_ = {name: [r["load"] for r in rs if r["wall"] >= MIN_LOAD_WINDOW] for name, rs in (("lamina", L), ("cycles", C))}
    load = {name: float(np.mean(v)) if v else float("nan") for name, v in long_.items()}
    return {"metric": key, "curves": {"lamina": cl, "cycles": cc}, "costs": costs, "targets": rows,
            "cpu_ratio": geo("cpu_ratio"), "spp_ratio": geo("spp_ratio"), "cpu_ratio_sampling": geo("cpu_ratio_sampling"),
            "cost_ratio": cost_ratio, "cost_ratio_rse": cost_ratio_rse,
            "slope": {"lamina": metrics.slope(cl["spp"], cl["err"]), "cycles": metrics.slope(cc["spp"], cc["err"])},
            "cost_ratio_total": costs["lamina"]["us_per_px_sample_total"] / costs["cycles"]["us_per_px_sample_total"],
            "any_extrapolated": any(r["extrapolated"] for r in rows), "background_load": load,
            "lamina_startup": sr.startup,
            "retries": sr.retries, "load_avg": list(sr.load_avg)}


def run_all(scenes: list[PeerScene], quick: bool, cache: Path, log, workers: int | None = None,
            child_log: Path | None = None) -> tuple[list[SceneRun], dict]:
    workers = workers or os.cpu_count() or 1
    t0 = time.perf_counter()
    with CyclesProcess(child_log) as cy:
        info = {"bpy_import_cpu": cy.hello["import_cpu"], "bpy_import_wall": cy.hello["import_wall"],
                "threads": workers}
        results = []
        for sc in scenes:
            results.append(measure_scene(cy, sc, quick, cache, log, workers))
        info["blender"] = cy.version
    info["elapsed"] = time.perf_counter() - t0
    return results, info
