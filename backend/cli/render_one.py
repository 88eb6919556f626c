"""One scene file rendered to its outputs (``render`` with one scene; each frame of an animation,
frames.py): outputs checked before the render, the EXR (and PNG preview) written after it,
rescued to the temporary folder if that fails, partial results for the add-on, the progress
display and the summary."""
from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import LaminaError


class ProgressPrinter:
    def __init__(self, mode: str):
        import threading
        self.mode = mode
        self.last = 0.0
        self.lock = threading.Lock()      # frames of an animation may report from two threads

    def emit(self, event: dict) -> None:
        with self.lock:
            self._emit(event)

    def _emit(self, event: dict) -> None:
        if self.mode == "json":
            sys.stdout.write(json.dumps(event) + "\n")
            sys.stdout.flush()
        elif self.mode == "bar":
            kind = event.get("event")
            if kind == "progress":
                now = time.perf_counter()
                if now - self.last < 0.2 and event["fraction"] < 1:
                    return
                self.last = now
                frac = event["fraction"]
                bar = "#" * int(frac * 30)
                sys.stderr.write(f"\r[{bar:<30}] {frac * 100:5.1f}%  {event['samples_per_second'] / 1e3:8.1f} k samples/s"
                                 f"  elapsed {event['elapsed']:6.1f} s  ETA {event['eta']:6.1f} s ")
                sys.stderr.flush()
            elif kind in ("warning",):
                sys.stderr.write(f"warning: {event['message']}\n")
            elif kind in ("compiling", "compiled"):
                sys.stderr.write(event["message"] + "\n")
            elif kind == "done":
                sys.stderr.write("\n")
        elif event.get("event") == "warning":
            sys.stderr.write(f"warning: {event['message']}\n")
        elif event.get("event") in ("compiling", "compiled"):
            sys.stderr.write(event["message"] + "\n")


def options_from_args(args):
    from ..render import RenderOptions
    return RenderOptions(spp=args.spp, seed=args.seed, workers=args.workers,
                         time_limit=args.time_limit, noise_target=args.noise_target,
                         min_spp=args.min_spp, max_bounces=args.max_bounces, sampler=args.sampler,
                         resolution=args.resolution, parallel=args.parallel,
                         cluster=args.cluster, cluster_files=args.cluster_files,
                         cluster_timeout=args.cluster_timeout, view=getattr(args, "view", None))


def check_outputs(output: Path, png: str | None, partial: str | None) -> None:
    """Every output is checked before rendering: a render must not be lost to a typo'd folder."""
    from ..imageio import check_writable
    if output.suffix.lower() != ".exr":
        raise LaminaError(f"output must be an .exr file, got {output}")
    check_writable(output, "output")
    if png:
        check_writable(Path(png), "preview (--png)")
    if partial:
        check_writable(Path(partial), "partial result (--partial)")


def render_scene(args, scene_path: Path, output: Path, png: str | None, printer, emit=None,
                 options=None, on_renderer=None) -> int:
    """Render one scene file to ``output`` (and ``png``); returns the exit status (0, or 130 when
    interrupted); LaminaError for what went wrong. ``emit`` (default ``printer.emit``) receives
    the events; ``on_renderer`` (default: SIGINT/SIGTERM handlers) the Renderer before it runs."""
    from ..render import Renderer, install_signal_handlers
    from ..scene.loader import load_scene

    emit = emit or printer.emit
    check_outputs(output, png, args.partial)
    from ..scene.loader import HEAVY_SCENE_NOTICE
    from ..scene.reader import MISSING_TEXTURES
    token = HEAVY_SCENE_NOTICE.set(lambda message: emit({"event": "warning", "message": message}))
    strict = MISSING_TEXTURES.set("error" if getattr(args, "strict", False) else None)
    try:
        scene = load_scene(scene_path)
    finally:
        HEAVY_SCENE_NOTICE.reset(token)
        MISSING_TEXTURES.reset(strict)
    options = options or options_from_args(args)
    options.apply(scene)
    if args.resolution is not None:
        from ..limits import film_memory_problem
        problem = film_memory_problem(scene.width, scene.height)
        if problem:
            raise LaminaError(f"--resolution {args.resolution[0]}x{args.resolution[1]}: {problem}")
    for w in scene.warnings:
        emit({"event": "warning", "message": w})
    from ..limits import cpu_count
    if args.cluster and args.workers is not None:
        emit({"event": "warning", "message": "--workers is ignored with --cluster: "
              "the cluster's workers render (start them with the threads you want)"})
    elif args.workers is not None and args.workers > cpu_count():
        emit({"event": "warning", "message":
              f"--workers {args.workers} is more than the {cpu_count()} core(s) this "
              f"process may use: the extra workers only compete for them (and, for "
              f"scenes rendered with worker processes, each holds its own copy of the scene)"})
    source = str(scene_path.resolve())

    def write_partial(film, spp_done):
        _write_partial(Path(args.partial), film)
        emit({"event": "partial", "path": str(Path(args.partial).resolve()), "spp": spp_done})

    renderer = Renderer(scene, source, options, emit, write_partial if args.partial else None,
                        args.partial_interval)
    (on_renderer or install_signal_handlers)(renderer)
    result = renderer.run()
    denoised = None
    if getattr(args, "denoise", False) and result.film.counts().any():
        from ..denoise import denoise
        film = result.film
        with np.errstate(all="ignore"):
            denoised = denoise(film.combined(), film.albedo_image(), film.normal_image())
    changed = write_outputs_or_rescue(result, output, png, args.half, denoised)
    if args.partial:
        _write_partial(Path(args.partial), result.film, aovs=True)
    if changed:
        limit = "65504 (half float; write float without --half)" if args.half else "3.4e38 (float32)"
        emit({"event": "warning", "message":
              f"{changed} value(s) in {output} were not finite or beyond ±{limit}: written "
              f"as 0 (NaN) or clamped. The scene holds values too large to render "
              f"(light powers, emission, colours or textures)"})
    if result.error:
        if args.partial:               # the add-on shows the last partial result it was told of
            emit({"event": "partial", "path": str(Path(args.partial).resolve()), "spp": result.spp_done})
        raise LaminaError(f"{result.error}; {output} holds the samples done before that")
    summary = summarise(result)
    emit({"event": "done", "path": str(output.resolve()), **summary})
    if printer.mode != "json":
        print(format_summary(summary, output), file=sys.stderr)
    return 130 if result.interrupted else 0


def write_outputs(result, output: Path, png: str | None, half: bool = False, denoised=None) -> int:
    """The EXR (and preview); returns how many values were not finite or out of the EXR's range
    (imageio.write_exr writes them as 0 or clamped). With ``denoised`` (render --denoise) the
    main RGBA and the preview are the denoised image and the layer ``noisy`` keeps the render's
    own (as Cycles' Noisy Image pass)."""
    from ..imageio import write_exr, write_preview
    film = result.film
    # Sums that overflowed (absurd but legal scene values) give Inf/NaN here: no warnings from
    # NumPy, the writer makes them finite and the caller says how many there were.
    with np.errstate(all="ignore"):
        rgb = film.combined()
        alpha = _alpha(film)
        shown = rgb if denoised is None else denoised
        layers = {"": np.concatenate([shown, alpha], axis=2), "albedo": film.albedo_image(),
                  "normal": film.normal_image(), "variance": film.variance_of_mean(),
                  "samples": film.counts()[:, :, None].astype(np.float32)}
        if denoised is not None:
            layers["noisy"] = np.concatenate([rgb, alpha], axis=2)
        layers.update(film.pass_images())        # the requested data passes (docs/cli.md)
        changed = write_exr(output, layers, half=half)
        if png:
            write_preview(png, shown)
    return changed


def write_outputs_or_rescue(result, output: Path, png: str | None, half: bool = False, denoised=None) -> None:
    """write_outputs; if that fails after all (disk full, folder removed during the render), the
    image is written to the temporary folder instead and the error names where it went."""
    try:
        return write_outputs(result, output, png, half, denoised)
    except (LaminaError, OSError) as exc:
        rescue = Path(tempfile.gettempdir()) / f"lamina-rescued-{output.stem[:100]}-{os.getpid()}.exr"
        try:
            write_outputs(result, rescue, None, half, denoised)
        except (LaminaError, OSError) as exc2:
            raise LaminaError(f"{exc}; writing the render to {rescue} failed too: {exc2}") from exc
        raise LaminaError(f"{exc}; the render was saved to {rescue} instead") from exc


def _alpha(film) -> np.ndarray:
    """Alpha: coverage with a transparent film (Blender's Film > Transparent), else 1 where sampled."""
    if getattr(film, "transparent", False):
        return film.coverage().astype(np.float32)[:, :, None]
    return (film.counts() > 0).astype(np.float32)[:, :, None]


def _write_partial(path: Path, film, aovs: bool = False) -> None:
    from ..imageio import write_npy
    with np.errstate(all="ignore"):
        rgb = film.combined()
        alpha = _alpha(film)
        write_npy(path, np.concatenate([rgb, alpha], axis=2))
        if aovs:
            write_npy(path.with_suffix(".aovs.npy"), np.concatenate([film.albedo_image(), film.normal_image()], axis=2))
            for name, image in film.pass_images().items():
                write_npy(pass_npy_path(path, name), image)


def pass_npy_path(partial: Path, pass_name: str) -> Path:
    """Where the final data pass ``pass_name`` (its EXR name, e.g. 'Object Index') goes next to
    the partial result: ``partial.pass-object-index.npy`` (add-on protocol, docs/cli.md)."""
    slug = pass_name.lower().replace(" ", "-")
    return partial.with_suffix(f".pass-{slug}.npy")


def summarise(result) -> dict:
    st = result.stats
    paths = st.get("paths", 0)
    rays = st.get("rays", 0)
    out = {"elapsed": round(result.elapsed, 3), "interrupted": result.interrupted,
           "paths": paths, "rays": rays, "worker_cpu_time": round(result.cpu_time, 3),
           "paths_per_second": round(paths / max(result.elapsed, 1e-9), 1),
           "rays_per_second": round(rays / max(result.elapsed, 1e-9), 1)}
    out.update(samples_held(result.film.count))
    for k, v in st.items():
        if k not in ("paths", "rays", "cpu_time", "master_cpu_time"):
            out[k] = v
    return out


def samples_held(count) -> dict:
    """What the image holds, read from the film's per-pixel sample counts (the EXR's): ``spp`` the
    most any pixel has, and where pixels differ (a time limit stopped inside a pass, adaptive
    sampling stopped converged pixels) ``spp_min`` and ``spp_mean`` too. Counting whole passes
    instead under-reported a time-limited render."""
    if count.size == 0:
        return {"spp": 0}
    lo, hi = int(count.min()), int(count.max())
    if lo == hi:
        return {"spp": hi}
    return {"spp": hi, "spp_min": lo, "spp_mean": round(float(count.mean()), 2)}


#: Statistics that describe the work done, not a problem: in the summary (``--json``), not printed.
QUIET_STATISTICS = ("layered_pdfs_deferred",)


def format_summary(summary: dict, output: Path) -> str:
    spp = (f"{summary['spp_min']}–{summary['spp']} spp, mean {summary['spp_mean']:.1f}"
           if "spp_min" in summary else f"{summary['spp']} spp")
    lines = [f"wrote {output}  ({spp}, {summary['elapsed']:.2f} s, "
             f"{summary['paths_per_second'] / 1e3:.1f} k paths/s, {summary['rays_per_second'] / 1e6:.2f} M rays/s)"]
    extra = {k: v for k, v in summary.items() if k not in ("elapsed", "spp", "spp_min", "spp_mean",
                                                          "interrupted", "paths", "rays",
                                                          "worker_cpu_time", "paths_per_second", "rays_per_second")
             and k not in QUIET_STATISTICS}
    if extra:
        lines.append("statistics: " + ", ".join(f"{k} = {v}" for k, v in sorted(extra.items())))
    if summary["interrupted"]:
        lines.append("render interrupted: the image holds the samples done so far")
    return "\n".join(lines)
