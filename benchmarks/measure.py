"""Timed renders, cached references, error metrics and fits for the benchmark report.

Timing: ``wall`` is the elapsed time of scene load + render (what a user waits for, including
worker start-up and the embree build); ``cpu`` is the CPU time of this process and of every worker
process it started and reaped (``getrusage`` of self + children), so it does not depend on how
busy the shared machine is.

Errors against a reference R (rendered once with many samples and cached): for an image I,
``mse_raw`` = mean over pixels and channels of (I − R)². Since I and R are independent and both
unbiased, E[mse_raw] = MSE(I) + MSE(R); MSE(R) is estimated from R's own per-pixel variance of the
mean (``ref_mse``) and subtracted: ``mse`` = mse_raw − ref_mse (the number plotted, as RMSE).
``relmse`` = mean of (I − R)² / (R² + ε) with ε = (0.1 · mean luminance of R)² — a scale-free
choice so that black pixels do not dominate — with the same correction.
``pred_mse`` = mean of I's own variance of the mean: for an unbiased estimator whose variance is
well estimated, mse / pred_mse ≈ 1 (the "consistency ratio"; > 1 means bias or heavy tails).
"""
from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import resource
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .scenes import REPO, referenced_files


@dataclass
class Run:
    label: str
    spp: int
    seed: int
    workers: int
    wall: float
    cpu: float
    image: np.ndarray          # (H, W, 3) float64
    var: np.ndarray            # (H, W, 3) variance of the pixel mean
    counts: np.ndarray         # (H, W) samples per pixel
    stats: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)

    @property
    def mean_spp(self) -> float:
        return float(self.counts.mean())

    def summary(self) -> dict:
        return {"label": self.label, "spp": self.spp, "mean_spp": round(self.mean_spp, 3), "seed": self.seed,
                "workers": self.workers, "wall": round(self.wall, 4), "cpu": round(self.cpu, 4),
                **{k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in self.metrics.items()},
                "stats": {k: v for k, v in self.stats.items() if k not in ("cpu_time", "master_cpu_time")}}


def _cpu_now() -> float:
    s = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def apply_patch(data: dict, patch: dict | None) -> dict:
    """Deep-merge ``patch`` into a copy of a scene dict (a variant is data, e.g.
    ``{"render": {"layered": {"estimator": "uni"}}}``)."""
    out = copy.deepcopy(data)

    def merge(a, b):
        for k, v in b.items():
            if isinstance(v, dict) and isinstance(a.get(k), dict):
                merge(a[k], v)
            else:
                a[k] = copy.deepcopy(v)
    merge(out, patch or {})
    return out


def render(data: dict, spp: int, seed: int, workers: int = 1, label: str = "", noise_target: float | None = None,
           min_spp: int | None = None) -> Run:
    """Load and render a scene dict in this process (workers > 1: worker processes)."""
    from backend.render import Renderer, RenderOptions
    from backend.scene.loader import load_scene_data

    data = copy.deepcopy(data)
    data.setdefault("render", {})
    t0 = time.perf_counter()
    c0 = _cpu_now()
    scene = load_scene_data(copy.deepcopy(data), f"<{label or 'bench'}>")
    opts = RenderOptions(spp=spp, seed=seed, workers=workers, noise_target=noise_target, min_spp=min_spp)
    opts.apply(scene)
    result = Renderer(scene, (data, f"<{label or 'bench'}>", None), opts).run()
    wall = time.perf_counter() - t0
    cpu = _cpu_now() - c0
    film = result.film
    return Run(label, spp, seed, workers, wall, cpu, film.combined().astype(np.float64),
               film.variance_of_mean().astype(np.float64), film.counts().copy(), dict(result.stats))


# --------------------------------------------------------------------------- reference cache

def source_digest() -> str:
    """Hash of the renderer's source: a cached reference is reused only for identical code."""
    h = hashlib.sha256()
    for p in sorted((REPO / "backend").rglob("*.py")):
        h.update(str(p.relative_to(REPO)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def reference_key(data: dict, spp: int, seed: int) -> str:
    h = hashlib.sha256()
    h.update(json.dumps(data, sort_keys=True).encode())
    h.update(f"{spp}/{seed}/{source_digest()}".encode())
    for f in referenced_files(data):
        if f.is_file():
            h.update(f.read_bytes())
    for m in data.get("materials", {}).values():
        if isinstance(m, str):
            # A preset named in the scene: the image depends on its file, not on its name.
            from backend.presets import find_preset
            f = find_preset(m)
            if f is not None:
                h.update(f.read_bytes())
    return h.hexdigest()[:20]


def reference(data: dict, name: str, spp: int, cache: Path, log=print, seed: int = 7_000_001) -> tuple[Run, bool]:
    """The high-sample reference of a scene: from the cache, or rendered with every core and stored.
    Returns (run, was_cached).

    References use the independent sampler whatever the scene says: their noise (subtracted from
    every measured MSE) is estimated from the per-pixel variance of the mean, which assumes
    independent samples. With the scrambled Sobol sampler that estimate overstates the noise
    (measured: the furnace's 256-spp error came out below it, an RMSE of NaN)."""
    data = {**data, "render": {**data.get("render", {}), "sampler": "independent"}}
    key = reference_key(data, spp, seed)
    path = cache / f"ref-{name}-{key}.npz"
    if path.exists():
        z = np.load(path, allow_pickle=False)
        meta = json.loads(str(z["meta"]))
        run = Run(f"{name} reference", meta["spp"], meta["seed"], meta["workers"], meta["wall"], meta["cpu"],
                  z["image"], z["var"], z["counts"], meta.get("stats", {}))
        return run, True
    workers = os.cpu_count() or 1
    log(f"  rendering reference for {name}: {spp} spp with {workers} worker(s)...")
    run = render(data, spp, seed, workers, f"{name} reference")
    cache.mkdir(parents=True, exist_ok=True)
    meta = {"spp": spp, "seed": seed, "workers": workers, "wall": run.wall, "cpu": run.cpu,
            "stats": {k: v for k, v in run.stats.items()}}
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, image=run.image, var=run.var, counts=run.counts, meta=json.dumps(meta))
    tmp.replace(path)
    return run, False


# --------------------------------------------------------------------------- metrics

LUM = np.array([0.2126, 0.7152, 0.0722])


def reference_noise(ref: Run) -> dict:
    lum = float((ref.image @ LUM).mean())
    eps = (0.1 * lum) ** 2 if lum > 0 else 1e-6
    w = 1.0 / (ref.image ** 2 + eps)
    return {"ref_mse": float(ref.var.mean()), "ref_relmse": float((ref.var * w).mean()), "eps": eps}


def errors(run: Run, ref: Run, noise: dict | None = None) -> dict:
    noise = noise or reference_noise(ref)
    d2 = (run.image - ref.image) ** 2
    w = 1.0 / (ref.image ** 2 + noise["eps"])
    mse_raw = float(d2.mean())
    rel_raw = float((d2 * w).mean())
    mse = mse_raw - noise["ref_mse"]
    rel = rel_raw - noise["ref_relmse"]
    pred = float(run.var.mean()) if run.counts.min() >= 2 else float("nan")
    out = {"mse_raw": mse_raw, "mse": mse, "rmse": math.sqrt(mse) if mse > 0 else float("nan"),
           "relmse_raw": rel_raw, "relmse": rel, "pred_mse": pred,
           "consistency": mse / pred if pred and pred > 0 and np.isfinite(pred) else float("nan")}
    return out


def fit_loglog(x, y) -> tuple[float, float, float]:
    """Least-squares line through (log x, log y): slope, intercept, standard error of the slope."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    lx, ly = np.log(x[ok]), np.log(y[ok])
    if lx.size < 2:
        return float("nan"), float("nan"), float("nan")
    A = np.stack([lx, np.ones_like(lx)], axis=1)
    coef, *_ = np.linalg.lstsq(A, ly, rcond=None)
    if lx.size > 2:
        resid = ly - A @ coef
        s2 = float(resid @ resid) / (lx.size - 2)
        se = math.sqrt(s2 / float(((lx - lx.mean()) ** 2).sum()))
    else:
        se = float("nan")
    return float(coef[0]), float(coef[1]), se


def fit_cost(spp, t) -> tuple[float, float]:
    """time ≈ t0 + c · spp (fixed start-up cost t0 [s], cost per sample per pixel c [s])."""
    spp, t = np.asarray(spp, float), np.asarray(t, float)
    A = np.stack([np.ones_like(spp), spp], axis=1)
    (t0, c), *_ = np.linalg.lstsq(A, t, rcond=None)
    return float(t0), float(c)


def time_at_error(times, errs, target: float) -> float:
    """Time a series needs to reach ``target`` error, from the least-squares line through its
    (log time, log error) points (robust to the scatter of independent renders)."""
    slope, icpt, _ = fit_loglog(times, errs)
    if not (np.isfinite(slope) and slope < 0 and target > 0):
        return float("nan")
    return math.exp((math.log(target) - icpt) / slope)
