"""Figures of the report (matplotlib, Agg backend, PNG)."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .measure import fit_loglog  # noqa: E402

DPI = 110


def tonemap(img: np.ndarray) -> np.ndarray:
    """Linear RGB → display sRGB, exposure set so the 99th luminance percentile maps to 1."""
    lum = img @ np.array([0.2126, 0.7152, 0.0722])
    scale = np.percentile(lum, 99) if np.any(lum > 0) else 1.0
    x = np.clip(img / max(scale, 1e-12), 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _guide(ax, xs, ys, slope=-0.5):
    """A dashed slope −½ line through the geometric centre of the points."""
    xs, ys = np.asarray(xs, float), np.asarray(ys, float)
    ok = (xs > 0) & (ys > 0) & np.isfinite(ys)
    if ok.sum() < 2:
        return
    lx, ly = np.log(xs[ok]), np.log(ys[ok])
    cx, cy = lx.mean(), ly.mean()
    gx = np.array([lx.min(), lx.max()])
    ax.plot(np.exp(gx), np.exp(cy + slope * (gx - cx)), ls=":", color="0.5", lw=1, label="slope −½")


def series_axes(ax, series: list, x: str, y: str, xlabel: str, ylabel: str, guide: bool = True):
    """series: list of (label, list of run-summary dicts). Points + least-squares fit per series."""
    markers = "osD^v<>p*"
    for i, (label, rows) in enumerate(series):
        xs = [r[x] for r in rows]
        ys = [r[y] for r in rows]
        s, icpt, _ = fit_loglog(xs, ys)
        lab = f"{label} (slope {s:+.2f})" if np.isfinite(s) else label
        pts = ax.loglog(xs, ys, markers[i % len(markers)], ms=4, label=lab)[0]
        if np.isfinite(s):
            xv = np.array([min(v for v in xs if v > 0), max(xs)])
            ax.loglog(xv, np.exp(icpt) * xv ** s, "-", color=pts.get_color(), lw=1)
    if guide and series:
        xs = [r[x] for r in series[0][1]]
        ys = [r[y] for r in series[0][1]]
        _guide(ax, xs, ys)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=7)


def scene_figure(path: Path, title: str, preview: np.ndarray | None, series: list, x: str = "cpu",
                 xlabel: str = "CPU time [s]") -> None:
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), gridspec_kw={"width_ratios": [1, 1.3, 1.3]})
    if preview is not None:
        axes[0].imshow(tonemap(preview), interpolation="nearest")
        axes[0].set_title("reference", fontsize=9)
    axes[0].axis("off")
    series_axes(axes[1], series, x, "rmse", xlabel, "RMSE (reference noise removed)")
    series_axes(axes[2], series, x, "relmse", xlabel, "relative MSE")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def comparison_figure(path: Path, title: str, panels: list) -> None:
    """panels: list of (panel title, series, x key, x label)."""
    fig, axes = plt.subplots(1, len(panels), figsize=(6.2 * len(panels), 4.2), squeeze=False)
    for ax, (ptitle, series, x, xlabel) in zip(axes[0], panels):
        series_axes(ax, series, x, "rmse", xlabel, "RMSE (reference noise removed)")
        ax.set_title(ptitle, fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def adaptive_figure(path: Path, title: str, uniform: list, adaptive: list, counts: np.ndarray | None) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(14, 4), gridspec_kw={"width_ratios": [1.2, 1.2, 1]})
    for ax, y, ylabel in ((axes[0], "rmse", "RMSE"), (axes[1], "relmse", "relative MSE")):
        series_axes(ax, [("uniform", uniform), ("adaptive (noise_target)", adaptive)], "cpu", y,
                    "CPU time [s]", ylabel, guide=False)
        for r in adaptive:
            if r.get("noise_target") and np.isfinite(r[y]) and r[y] > 0:
                ax.annotate(f"{r['noise_target']:g}", (r["cpu"], r[y]), fontsize=6, xytext=(3, 3),
                            textcoords="offset points")
    if counts is not None:
        im = axes[2].imshow(counts, cmap="viridis", interpolation="nearest")
        fig.colorbar(im, ax=axes[2], fraction=0.03)
        axes[2].set_title("samples per pixel (tightest target)", fontsize=9)
    axes[2].axis("off")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def bar_figure(path: Path, title: str, labels: list, means: list, errs: list, ylabel: str) -> None:
    fig, ax = plt.subplots(figsize=(max(4, 1.4 * len(labels)), 3.2))
    ax.bar(range(len(labels)), means, yerr=[2 * e for e in errs], capsize=4, color="0.6")
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, fontsize=7, rotation=15)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    lo = min(m - 3 * e for m, e in zip(means, errs)) if means else 0
    if math.isfinite(lo) and lo > 0:
        ax.set_ylim(lo * 0.9, None)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
