"""The "Lamina vs Cycles" section of the benchmark report: Markdown, figures and the summary lines."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import agree  # noqa: E402
from .run import REF_SPLIT  # noqa: E402
from .scenes import FILM_FILTER, MAX_BOUNCES, RR_DEPTH  # noqa: E402

DPI = 110
COLOURS = {"lamina": "tab:blue", "cycles": "tab:orange"}

#: (setting, value for both, how) — every setting made equal, with what it took.
EQUAL = [
    ("scene", "one Lamina scene dict per scene (`benchmarks/peers/scenes.py`)",
     "Lamina loads it; `convert.py` + `to_cycles.py` build the Blender scene from it"),
    ("geometry", "the triangles and per-corner normals of Lamina's loader",
     "written to Blender meshes as they are (custom normals; flat faces where Lamina's are flat)"),
    ("camera", "the same `to_world` and image-plane frame",
     "checked: Blender's `view_frame`, normalised, equals the description to < 1e-7"),
    ("resolution", "96 × 96 (layered and presets scenes 80 × 80), 100 %", ""),
    ("pixel filter", "Blackman-Harris spanning ±1.5 px (Cycles' default look)",
     f"`film.filter` width {FILM_FILTER['width']:g} = Cycles `filter_width` {FILM_FILTER['width']:g} "
     "(the same definition: Cycles' filter_table)"),
    ("max bounces", f"{MAX_BOUNCES} in total", "Cycles' diffuse / glossy / transmission limits raised to the same "
     "(defaults 4 / 4 / 12), volume 0: Lamina has only the total"),
    ("Russian roulette", "from the same surface, survival min(1, √max throughput), decided after the emission found",
     f"Lamina `rr_depth` {RR_DEPTH} ↔ Cycles `min_light_bounces` {RR_DEPTH - 2} (Cycles' kernel adds 1: no roulette at "
     "bounce ≤ min + 1, the camera hit being bounce 0; Lamina: at surfaces with index ≥ rr_depth)"),
    ("clamping", "off; everyday and presets: indirect at 10 (Cycles' default)",
     "Lamina `clamp` = Cycles `sample_clamp_indirect` (the same definition: the sum of RGB of what a vertex after "
     "the camera hit gathers), `sample_clamp_direct` 0"),
    ("Filter Glossy", "off", "Cycles `blur_glossy` 0 (default 1)"),
    ("caustics", "reflective and refractive on", "Lamina's paths are unbiased"),
    ("denoising, adaptive sampling", "off", "Cycles' defaults are on"),
    ("threads", "all cores", "Lamina `workers` = os.cpu_count(); Cycles `threads_mode` FIXED, `threads` = os.cpu_count(), CPU device"),
    ("microfacets", "GGX, height-correlated Smith, single scattering",
     "Cycles `distribution` GGX (its default is Multiscatter GGX); roughness slider √α (Cycles squares it)"),
    ("conductors", "Lamina's measured RGB (eta, k) (`backend/materials/metals.py`)",
     "Metallic BSDF in Physical Conductor mode with the same numbers"),
    ("dielectrics / diffuse", "same IOR and roughness / Lambert", "Glass BSDF (GGX) / Diffuse BSDF with roughness 0"),
    ("area lights", "one-sided, power normalised by area, `spread` as given",
     "visible to camera rays only where the scene says so (the Cornell light); lights never occlude"),
    ("point light + IES", "same power, radius 0, soft falloff off",
     "Blender's default soft falloff is on: set from the scene; profile through an IES Texture node (Fac → Strength)"),
    ("emitter sidedness", "area lights emit from their −Z side only in both", "no mesh emitters in these scenes"),
    ("sun", "the same strength (W/m² of irradiance), angular diameter, colour and direction",
     "Cycles SUN light: `energy` = strength, `angle` = the same diameter, `matrix_world` = `to_world`; hidden from "
     "camera rays in both"),
    ("Principled BSDF (everyday; the presets scene's ground)", "one set of Principled settings per material",
     "Cycles: a Principled BSDF node with them (GGX, every other input at Blender's default); Lamina: what the add-on "
     "exports for them (`addon/export/principled.py`)"),
    ("world", "constant colour × strength (or black)", "Background node"),
    ("shadow terminator", "no offset", "Cycles `shadow_terminator_geometry_offset` 0 (default 0.1)"),
    ("per-render start-up", "every render loads the scene and builds its BVH",
     "Cycles persistent data off; Lamina builds the scene in its master and in each worker process"),
    ("seeds", "independent per render", "Lamina `seed`, Cycles `seed` (animated seed off)"),
]

#: (what, Lamina, Cycles, why it stays different)
DIFFERENT = [
    ("glass throughput", "radiance-mode BTDF (1/η² entering a denser medium), so roulette sees 1/η² inside glass",
     "no η² factor", "each renderer's BSDF convention (the same image for closed objects)"),
    ("sample sequence", "Owen-scrambled Sobol on the camera hit, hashed numbers deeper", "tabulated Sobol at every bounce (Cycles' default)",
     "each renderer's default sampler"),
    ("light selection", "`local`: ∝ power received at the shading point", "light tree (default on)",
     "each renderer's default sampler"),
    ("weak shadow rays", "always traced", "light threshold 0.01 (roulette on weak light samples, default)",
     "Cycles' default sampler; unbiased"),
    ("constant world sampling", "uniform over the sphere", "world importance map `AUTOMATIC`", "defaults"),
    ("process model", "master + one worker process per core, started for each render (spawn)",
     "one process, one thread per core", "architecture"),
    ("arithmetic", "float64 shading, float32 ray casting (embree)", "float32 (embree)", "architecture"),
    ("layered scene material", "2-interface stack (random walk between coat and body)",
     "Principled BSDF with Coat (albedo-scaling layering), base specular off",
     "different materials: compared at equal *own relative* noise, images not compared"),
    ("Principled BSDF (everyday)", "the add-on's export: dielectric over Lambert, conductor, coat, glass, chosen to have "
     "Cycles' albedo under uniform light", "Principled BSDF (albedo-scaling layers, F82 metal)",
     "the same .blend as an artist renders it in each; the lobes differ, so lit regions may differ by a few percent "
     "(the agreement check shows by how much)"),
    ("presets scene material", "the layered presets (media, Beckmann interfaces, ...)",
     "hand-made Principled stand-ins with each preset's albedo (`scenes.PRESET_PRINCIPLED`)",
     "different materials: compared at equal *own relative* noise, images not compared"),
]


def _fmt(x, d=3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    if x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e5):
        return f"{x:.{d - 1}e}"
    return f"{x:.{d}g}"


def _load(x: float) -> str:
    return f"{x:.2f}" if math.isfinite(x) else "– (runs < 0.5 s)"


def _display(img: np.ndarray, scale: float) -> np.ndarray:
    x = np.clip(img / max(scale, 1e-12), 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _region_map(shape, results, value) -> np.ndarray:
    out = np.full(shape, np.nan)
    for (name, mask), r in results:
        if name != "whole image":          # drawn region by region; the whole image is in the table
            out[mask] = value(r)
    return out


def scene_figure(path: Path, sr, summ: dict, regions: list) -> None:
    L, C = sr.refs["lamina"]["image"], sr.refs["cycles"]["image"]
    lum = C @ np.array([0.2126, 0.7152, 0.0722])
    scale = float(np.percentile(lum, 99)) if np.any(lum > 0) else 1.0
    fig, ax = plt.subplots(1, 5, figsize=(19, 3.9), gridspec_kw={"width_ratios": [1, 1, 1.15, 1.35, 1.35]})
    ax[0].imshow(_display(L, scale), interpolation="nearest")
    ax[0].set_title(f"Lamina reference ({sr.refs['lamina']['spp']} spp)", fontsize=8)
    ax[1].imshow(_display(C, scale), interpolation="nearest")
    ax[1].set_title(f"Cycles reference ({sr.refs['cycles']['spp']} spp)", fontsize=8)
    pairs = list(zip(regions, sr.agreement))
    if sr.scene.same_material:
        im = ax[2].imshow(_region_map(L.shape[:2], pairs, lambda r: float(np.max(np.abs(r.z)))), cmap="viridis",
                          vmin=0, vmax=max(agree.K_SIGMA * 1.5, 1), interpolation="nearest")
        ax[2].set_title(f"|z| per region (fail > {agree.K_SIGMA:g} σ)", fontsize=8)
    else:
        im = ax[2].imshow(_region_map(L.shape[:2], pairs, lambda r: float(np.mean(r.rel_diff)) * 100), cmap="RdBu_r",
                          vmin=-30, vmax=30, interpolation="nearest")
        ax[2].set_title("Lamina / Cycles − 1 per region [%]\n(different materials)", fontsize=8)
    fig.colorbar(im, ax=ax[2], fraction=0.046)
    for a in ax[:3]:
        a.axis("off")
    ylabel = "RMSE" if summ["metric"] == "rmse" else "relative RMSE"
    for a, x, xl in ((ax[3], "spp", "samples per pixel"), (ax[4], "cpu", "CPU time per render [s]")):
        for name in ("lamina", "cycles"):
            cv = summ["curves"][name]
            runs = [r for r in sr.runs if r["renderer"] == name]
            ys = [r[summ["metric"]] for r in runs]
            a.loglog([r[x] for r in runs], ys, "o", ms=3, alpha=0.45, color=COLOURS[name])
            a.loglog(cv[x], cv["err"], "-", color=COLOURS[name], label=f"{name.capitalize()} (mean of repeats)")
        for t in summ["targets"]:
            a.axhline(t["target"], ls=":", color="0.5", lw=0.8)
        a.set_xlabel(xl)
        a.set_ylabel(ylabel + " (own reference, its noise removed)", fontsize=8)
        a.grid(True, which="both", alpha=0.25)
        a.legend(fontsize=7)
    fig.suptitle(f"{sr.scene.name}: {sr.scene.title}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def ratio_figure(path: Path, rows: list) -> None:
    names = [r[0] for r in rows]
    keys = [("cpu_ratio", "CPU time, whole renders"), ("cpu_ratio_sampling", "CPU time, start-up excluded"),
            ("spp_ratio", "samples"), ("cost_ratio", "CPU per sample")]
    fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(names)), 3.6))
    w = 0.8 / len(keys)
    for k, (key, label) in enumerate(keys):
        vals = [r[1][key] for r in rows]
        ax.bar(np.arange(len(names)) + (k - (len(keys) - 1) / 2) * w, vals, w, label=label)
    ax.axhline(1, color="k", lw=0.8)
    ax.set_yscale("log")
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels(names, fontsize=8)
    ax.set_ylabel("Lamina / Cycles at equal error")
    ax.grid(True, axis="y", which="both", alpha=0.25)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _agreement_md(sr) -> list[str]:
    res, dark = sr.agreement, sr.darker
    v, vd = agree.verdict(res), agree.verdict(dark)
    md = []
    if sr.scene.same_material:
        md.append(f"**Agreement of the converged images: {'PASS' if v['ok'] else 'FAIL'}** — {v['regions']} regions, "
                  f"{v['failed']} outside {agree.K_SIGMA:g} σ{f' + {agree.REL_TOL:.1%}' if agree.REL_TOL else ''} "
                  f"(largest |z| {v['max_abs_z']:.2f}). **The same Lamina image 1 % darker: "
                  f"{'FAIL' if not vd['ok'] else 'PASS (the check cannot see 1 % here)'}** — "
                  f"{vd['failed']} of {vd['regions']} regions fail (largest |z| {vd['max_abs_z']:.1f}).")
    else:
        lum = np.array([0.2126, 0.7152, 0.0722])
        ratios = [float(r.mean_a @ lum / (r.mean_b @ lum)) for r in res if r.mean_b @ lum > 0]
        md.append("Different materials on the spheres, so the images are not expected to agree there; listed for "
                  f"information (Lamina / Cycles region means from {min(ratios):.2f} to {max(ratios):.2f}).")
    if sr.regions_dropped:
        md.append(f"Regions too small to test (< {agree.MIN_PIXELS} pixels): {', '.join(sr.regions_dropped)}.")
    md += ["", "<details><summary>Per-region table</summary>", "",
           "| region | pixels | Lamina (lum.) | Cycles (lum.) | Lamina/Cycles − 1 | max \\|z\\| | detectable (k σ / mean) | "
           "1 % darker: max \\|z\\| | result |", "|---|---|---|---|---|---|---|---|---|"]
    lum = np.array([0.2126, 0.7152, 0.0722])
    for r, d in zip(res, dark):
        a, b = float(r.mean_a @ lum), float(r.mean_b @ lum)
        det = float(np.max(agree.K_SIGMA * r.se / np.where(np.abs(r.mean_b) > 0, np.abs(r.mean_b), np.inf)))
        md.append(f"| {r.name} | {r.pixels} | {_fmt(a, 4)} | {_fmt(b, 4)} | {(a / b - 1) * 100 if b else float('nan'):+.2f} % | "
                  f"{float(np.max(np.abs(r.z))):.2f} | {det * 100:.2f} % | {float(np.max(np.abs(d.z))):.1f} | "
                  f"{'ok' if r.ok else 'FAIL'} |")
    md += ["", "</details>", ""]
    return md


def section(results: list, summaries: list, info: dict, link) -> str:
    """``link(path)`` gives the Markdown path of a figure."""
    md = ["## 0. Lamina vs Cycles", "",
          f"Each scene is described once (a Lamina scene dict) and rendered by Lamina and by Cycles "
          f"(bpy {info.get('blender', '?')}, CPU, {info['threads']} threads; Lamina {info['threads']} worker threads) "
          "with the settings below made equal. Every render is measured against its **own** renderer's converged "
          "reference (reference noise removed). Runs of the two renderers are interleaved pair by pair "
          "(order alternating A B / B A, independent seeds, "
          f"{'1 repeat' if info.get('quick') else '2 repeats'}); CPU time (process + children for Lamina, the bpy "
          "process's own threads for Cycles) is the clock. Equal-error figures are interpolated log-log between "
          "the measured points at targets inside both curves' range. *Total* CPU is the whole render as measured "
          "(scene load, worker start-up, BVH); *start-up excluded* = spp at the target × the marginal CPU per spp "
          "(slope of CPU time vs spp). Method and settings: docs/benchmarks.md, \"Lamina vs Cycles\".", "",
          f"Blender start-up (import bpy, once for the section): {info['bpy_import_cpu']:.2f} s CPU. "
          f"Section time: {info['elapsed'] / 60:.1f} min (references {'partly cached' if info.get('any_cached') else 'rendered'}).", ""]
    md += ["| scene | equal-error CPU, Lamina / Cycles: whole renders | start-up excluded | spp ratio | CPU µs per pixel-sample, "
           "marginal: Lamina / Cycles (ratio) | same, total at max spp | start-up CPU per render: Lamina / Cycles | "
           "images agree | 1 % darker fails | background load (cores): Lamina / Cycles runs; load avg start → end |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for sr, s in zip(results, summaries):
        cl, cc = s["costs"]["lamina"], s["costs"]["cycles"]
        v, vd = agree.verdict(sr.agreement), agree.verdict(sr.darker)
        agree_txt = (f"{'yes' if v['ok'] else '**NO**'} ({v['regions'] - v['failed']}/{v['regions']} regions)"
                     if sr.scene.same_material else "n/a (different materials)")
        dark_txt = f"{'yes' if not vd['ok'] else '**no**'} ({vd['failed']} regions)" if sr.scene.same_material else "–"
        ext = " (extrapolated)" if s["any_extrapolated"] else ""
        md.append(f"| {sr.scene.name}{' †' if not sr.scene.same_material else ''} | **{_fmt(s['cpu_ratio'])}×**{ext} | "
                  f"**{_fmt(s['cpu_ratio_sampling'])}×** ± {s['cost_ratio_rse'] * 100:.0f} % | {_fmt(s['spp_ratio'])}× | "
                  f"{_fmt(cl['us_per_px_sample'])} ± {_fmt(cl['us_per_px_sample_se'], 2)} / "
                  f"{_fmt(cc['us_per_px_sample'])} ± {_fmt(cc['us_per_px_sample_se'], 2)} ({_fmt(s['cost_ratio'])}×) | "
                  f"{_fmt(cl['us_per_px_sample_total'])} / "
                  f"{_fmt(cc['us_per_px_sample_total'])} | {_fmt(cl['t0'])} s / {_fmt(cc['t0'])} s | {agree_txt} | {dark_txt} | "
                  f"{_load(s['background_load']['lamina'])} / {_load(s['background_load']['cycles'])}; "
                  f"{s['load_avg'][0]:.2f} → {s['load_avg'][1]:.2f} |")
    md += ["", "± = standard error from the least-squares fit of CPU time against spp (the marginal cost, and through "
           "it the start-up-excluded ratio; the spp ratio's own scatter is not included).", "",
           "† different materials (Lamina's layered stacks vs Cycles' Principled BSDF stand-ins): the ratios "
           "compare CPU time to equal **own relative** noise (relative RMSE = RMSE / mean of the own reference), "
           "not equal work.", "",
           "Ratios are geometric means over the targets of each scene (per-target values below). A ratio > 1 means "
           "Lamina needs more. *Background load* is the CPU use of other processes during the runs (from /proc/stat, "
           "cores); the machine is shared, so absolute times move, while the interleaved ratios are what this "
           "section is for.", "", f"![ratios]({link('peers_ratios.png')})", ""]
    md += ["### Settings", "", "Made equal:", "", "| setting | both renderers | how |", "|---|---|---|"]
    md += [f"| {a} | {b} | {c} |" for a, b, c in EQUAL]
    kept = results[0].build["info"]["kept"] if results else {}
    md += ["", "Different (each renderer's own sampler and architecture; none can be set to match the other):", "",
           "| what | Lamina | Cycles | why |", "|---|---|---|---|"]
    md += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in DIFFERENT]
    md += ["", f"Cycles defaults kept, as read back from bpy: {', '.join(f'`{k}` = {v}' for k, v in kept.items())}.", ""]
    for sr, s in zip(results, summaries):
        md += [f"### Lamina vs Cycles: {sr.scene.name}", "", sr.scene.title + ".", "", f"![{sr.scene.name}]({link(f'peers_{sr.scene.name}.png')})", ""]
        metric = "RMSE" if s["metric"] == "rmse" else "relative RMSE"
        md += [f"Slope of {metric} against spp (log-log, all points): Lamina {_fmt(s['slope']['lamina'])}, Cycles "
               f"{_fmt(s['slope']['cycles'])} (−0.5 for independent samples).", ""]
        md += [f"| target {metric} | spp Lamina / Cycles | ratio | CPU s Lamina / Cycles (whole renders) | ratio | "
               "ratio, start-up excluded |", "|---|---|---|---|---|---|"]
        for t in s["targets"]:
            md.append(f"| {_fmt(t['target'])}{' (extrapolated)' if t['extrapolated'] else ''} | {_fmt(t['spp_lamina'])} / "
                      f"{_fmt(t['spp_cycles'])} | {_fmt(t['spp_ratio'])}× | {_fmt(t['cpu_lamina'])} / {_fmt(t['cpu_cycles'])} | "
                      f"{_fmt(t['cpu_ratio'])}× | {_fmt(t['cpu_ratio_sampling'])}× |")
        refs = sr.refs
        su, t0 = s["lamina_startup"], s["costs"]["lamina"]["t0"]
        n = results[0].build["info"]["set"]["threads"] if results else 1
        if su:
            md += ["", f"Start-up per render (fixed cost, intercept of CPU time vs spp): Lamina {_fmt(t0)} s, Cycles "
                   f"{_fmt(s['costs']['cycles']['t0'])} s (scene sync and BVH build in one process). Lamina's parts, "
                   f"measured alone (`startup.py`): scene load {_fmt(su['scene_load'])} s, embree build "
                   f"{_fmt(su['embree_build'])} s, integrator tables {_fmt(su['tables'])} s: "
                   f"{_fmt(su['predicted_t0'])} s; the rest, {_fmt(t0 - su['predicted_t0'])} s, is starting the "
                   f"{n} worker threads and the first work items' warm-up (and the fit's scatter)."]
        md += ["", f"References: Lamina {refs['lamina']['spp']} spp ({_fmt(refs['lamina']['cpu'])} s CPU"
               f"{', cached' if refs['lamina']['cached'] else ''}), Cycles {refs['cycles']['spp']} spp as {REF_SPLIT} independent "
               f"renders ({_fmt(refs['cycles']['cpu'])} s CPU{', cached' if refs['cycles']['cached'] else ''}). "
               f"Pairs run again because the background load moved: {s['retries']}.", ""]
        md += _agreement_md(sr)
    return "\n".join(md)


def summary_lines(results: list, summaries: list) -> list[str]:
    parts, costs, slopes = [], [], []
    for sr, s in zip(results, summaries):
        tag = " (different materials, equal own noise)" if not sr.scene.same_material else ""
        parts.append(f"{sr.scene.name} **{_fmt(s['cpu_ratio'], 2)}×** ({_fmt(s['cpu_ratio_sampling'], 2)}× without start-up; "
                     f"{_fmt(s['spp_ratio'], 2)}× the samples){tag}")
        costs.append(f"{sr.scene.name} {_fmt(s['costs']['lamina']['us_per_px_sample'], 2)} vs "
                     f"{_fmt(s['costs']['cycles']['us_per_px_sample'], 2)}")
        slopes.append(f"{sr.scene.name} {_fmt(s['slope']['lamina'], 2)} vs {_fmt(s['slope']['cycles'], 2)}")
    ok = [agree.verdict(sr.agreement)["ok"] for sr in results if sr.scene.same_material]
    dark = [not agree.verdict(sr.darker)["ok"] for sr in results if sr.scene.same_material]
    return [f"* **Lamina vs Cycles** — CPU time Lamina needs for the error Cycles reaches (Lamina / Cycles): "
            + "; ".join(parts) + ".",
            "* **CPU µs per pixel-sample** (marginal), Lamina vs Cycles: " + "; ".join(costs) + ". Converged images agree "
            f"region by region in {sum(ok)} of {len(ok)} equal-material scenes; a 1 % darker Lamina image fails the check "
            f"in {sum(dark)} of {len(dark)}.",
            "* **Error vs samples** (log-log slope), Lamina vs Cycles: " + "; ".join(slopes) + "."]
