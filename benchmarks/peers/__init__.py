"""Lamina vs Cycles at equal error (issue 14): the first section of the benchmark report.

    python -m benchmarks peers          this section alone → benchmarks/report-peers/
    python -m benchmarks                the full report, this section first

Modules, one job each: ``scenes`` (each scene described once, as a Lamina scene dict),
``convert`` (scene dict → a job for Blender, geometry from Lamina's loader), ``to_cycles`` (the
job → a bpy scene; runs only in the child), ``cycles_child`` / ``cycles_process`` (the bpy child
and the parent's handle on it), ``run`` (references and interleaved timed series), ``agree``
(region-by-region agreement of the converged images), ``metrics`` (errors, equal-error
interpolation, cost per sample), ``report`` (Markdown and figures).
"""
from __future__ import annotations

import math


def section(ctx, scene_names: list[str] | None = None) -> str:
    """Run the comparison and return its Markdown; results go to ``ctx.results["peers"]``."""
    from .cycles_process import bpy_available
    why = bpy_available()
    if why:
        ctx.skipped["peers"] = f"bpy not available: {why}"
        ctx.log(f"  Lamina vs Cycles skipped: bpy not available ({why})")
        return "\n".join(["## 0. Lamina vs Cycles", "", f"Not run: the `bpy` module cannot be imported here (`{why}`). "
                          "It is part of the development environment (requirements-dev.txt).", ""])
    from . import report, run
    from .scenes import PEER_SCENES
    scenes = [s for s in PEER_SCENES if scene_names is None or s.name in scene_names]
    ctx.cache.mkdir(parents=True, exist_ok=True)         # a fresh clone has no cache yet
    results, info = run.run_all(scenes, ctx.quick, ctx.cache, lambda m: ctx.log(m),
                                child_log=ctx.cache / "peers-cycles-child.log")
    info["quick"] = ctx.quick
    info["any_cached"] = any(r.refs[k]["cached"] for r in results for k in r.refs)
    summaries = [run.summarise(r) for r in results]
    for sr, s in zip(results, summaries):
        regs = run.agree.regions(sr.label_image, sr.label_names)
        report.scene_figure(ctx.report_dir / f"peers_{sr.scene.name}.png", sr, s, regs)
    report.ratio_figure(ctx.report_dir / "peers_ratios.png", [(sr.scene.name, s) for sr, s in zip(results, summaries)])

    def link(name: str) -> str:
        return (ctx.report_dir / name).relative_to(ctx.report_dir.parent).as_posix()

    md = report.section(results, summaries, info, link)
    ctx.results["peers"] = {
        "info": info, "summary_lines": report.summary_lines(results, summaries),
        "scenes": {sr.scene.name: {**{k: v for k, v in s.items()}, "build": sr.build,
                                   "runs": sr.runs, "same_material": sr.scene.same_material,
                                   "agreement": [r.summary() for r in sr.agreement],
                                   "darker_1pct": [r.summary() for r in sr.darker],
                                   "references": {k: {kk: vv for kk, vv in v.items() if kk not in ("image", "var")}
                                                  for k, v in sr.refs.items()}}
                   for sr, s in zip(results, summaries)}}
    ctx.log("  Lamina vs Cycles: " + "; ".join(f"{sr.scene.name} {s['cpu_ratio']:.2f}x CPU ({s['cpu_ratio_sampling']:.2f}x "
                                              f"without start-up), {s['spp_ratio']:.2f}x spp" for sr, s in zip(results, summaries)
                                              if math.isfinite(s['cpu_ratio'])))
    return md
