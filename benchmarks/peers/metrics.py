"""Error, cost and equal-error figures of the peer benchmark (pure NumPy, no renderer).

* Error of a render I against its *own* renderer's reference R: MSE = mean (I − R)² − mean Var[R]
  (the reference's own noise removed: I and R are independent, so E[(I − R)²] = MSE(I) + MSE(R)).
  RMSE = √MSE; *relative* RMSE = RMSE / mean(R), used where the two renderers render different
  materials (a brighter image is not a noisier one).
* Curves: per sample count, the MSE averaged over the repeated renders and the mean CPU time.
* Equal error: the spp and CPU time at which a curve reaches a target error, interpolated
  linearly in log-log between the two measured points that bracket it (extrapolated along the
  end segments' least-squares slope only when a target lies outside the measured range, and then
  flagged).
"""
from __future__ import annotations

import math

import numpy as np

from ..measure import fit_cost, fit_loglog


def error(img: np.ndarray, ref: np.ndarray, ref_var: np.ndarray) -> dict:
    mse_raw = float(((img - ref) ** 2).mean())
    mse = mse_raw - float(ref_var.mean())
    mean = float(ref.mean())
    rmse = math.sqrt(mse) if mse > 0 else float("nan")
    return {"mse_raw": mse_raw, "mse": mse, "rmse": rmse, "rel_rmse": rmse / mean if mean > 0 else float("nan")}


def curve(runs: list[dict], key: str) -> dict:
    """Group runs (dicts with spp, cpu, wall, mse, and ``key``'s squared form) by spp."""
    spps = sorted({r["spp"] for r in runs})
    out = {"spp": [], "cpu": [], "wall": [], "err": [], "n": []}
    for s in spps:
        rs = [r for r in runs if r["spp"] == s]
        mse = float(np.mean([r["mse"] for r in rs]))
        scale = 1.0 if key == "rmse" else 1.0 / rs[0]["ref_mean"]
        out["spp"].append(s)
        out["cpu"].append(float(np.mean([r["cpu"] for r in rs])))
        out["wall"].append(float(np.mean([r["wall"] for r in rs])))
        out["err"].append(math.sqrt(mse) * scale if mse > 0 else float("nan"))
        out["n"].append(len(rs))
    return out


def at_error(x: list, err: list, target: float) -> tuple[float, bool]:
    """x at which the error falls to ``target`` (log-log linear between bracketing points).
    Returns (x, extrapolated)."""
    x = np.asarray(x, float)
    e = np.asarray(err, float)
    ok = np.isfinite(e) & (e > 0) & (x > 0)
    x, e = x[ok], e[ok]
    if x.size < 2 or not (target > 0):
        return float("nan"), False
    lx, le, lt = np.log(x), np.log(e), math.log(target)
    for i in range(x.size - 1):
        a, b = le[i], le[i + 1]
        if (a - lt) * (b - lt) <= 0 and a != b:
            f = (lt - a) / (b - a)
            return float(math.exp(lx[i] + f * (lx[i + 1] - lx[i]))), False
    # Outside the measured range: extrapolate along the fit of the three nearest points.
    idx = np.argsort(np.abs(le - lt))[:3]
    slope, icpt, _ = fit_loglog(x[idx], e[idx])
    if not (np.isfinite(slope) and slope < 0):
        return float("nan"), True
    return float(math.exp((lt - icpt) / slope)), True


def targets(err_a: list, err_b: list, n: int = 3) -> list[float]:
    """``n`` errors spaced geometrically over the range both curves measured (their overlap);
    without overlap, the lowest errors of the curve that stops higher (the other one is then
    extrapolated, and flagged)."""
    a = [v for v in err_a if np.isfinite(v) and v > 0]
    b = [v for v in err_b if np.isfinite(v) and v > 0]
    if not a or not b:
        return []
    lo, hi = max(min(a), min(b)), min(max(a), max(b))
    if lo >= hi:
        worse = a if min(a) > min(b) else b
        lo, hi = min(worse), min(worse) * 2.0
    # Stay a little inside the overlap, where both curves have neighbours on both sides.
    llo, lhi = math.log(lo), math.log(hi)
    pad = 0.1 * (lhi - llo)
    return [float(math.exp(v)) for v in np.linspace(llo + pad, lhi - pad, n)]


def cost(runs: list[dict], pixels: int) -> dict:
    """Fixed cost t0 and marginal CPU per sample from time = t0 + c·spp; per pixel-sample in µs
    (= CPU seconds per spp per megapixel) both marginal and total at the largest spp."""
    spp = np.asarray([r["spp"] for r in runs], float)
    cpu = np.asarray([r["cpu"] for r in runs], float)
    t0, c = fit_cost(spp, cpu)
    # Standard error of the slope (ordinary least squares): the timing noise of a shared machine
    # makes the marginal cost of cheap scenes uncertain, and the report says by how much.
    resid = cpu - (t0 + c * spp)
    dof = max(spp.size - 2, 1)
    sxx = float(((spp - spp.mean()) ** 2).sum())
    se = math.sqrt(float(resid @ resid) / dof / sxx) if sxx > 0 else float("nan")
    top = float(spp.max())
    tot = float(cpu[spp == top].mean())
    return {"t0": t0, "per_spp": c, "us_per_px_sample": c / pixels * 1e6, "us_per_px_sample_se": se / pixels * 1e6,
            "us_per_px_sample_total": tot / (top * pixels) * 1e6, "max_spp": int(top)}


def slope(spp: list, err: list) -> float:
    """Least-squares slope of log error against log spp (−½ for independent samples; steeper
    where stratification pays); NaN with fewer than three finite points."""
    x = np.log(np.asarray(spp, float))
    y = np.log(np.asarray(err, float))
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3:
        return float("nan")
    return float(np.polyfit(x[ok], y[ok], 1)[0])
