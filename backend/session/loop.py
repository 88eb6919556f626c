"""The session's render loop: commands in, progressive frames out, idle at the sample target.

After every edit (a new generation) the image is rebuilt progressively:

1. *reduced passes*: one sample per pixel at 1/k of the width and height, k a power of two chosen
   so that the first pass has at most ``LEVEL_PIXELS`` pixels, then k/4, k/16 … while k > 1;
   each pass ends with a frame (``scale`` = k). The first of them is never interrupted: every
   generation that lives that long shows an image, however fast edits arrive;
2. *full resolution*: passes of one (or, for small images, a few) samples per pixel over the
   whole image (or the crop region), accumulated in a ``FilmAccumulator`` — the one ``render``
   uses — with a frame after each pass (at most every ``FRAME_INTERVAL`` seconds) and within long
   passes (pixels not reached yet show the last reduced pass);
3. at the sample target (0 = none) a final frame, an ``idle`` event, and the loop blocks on its
   command queue: no CPU is used until the next command.

Work is cut into items of about ``LANES_PER_ITEM`` paths (at least ``ITEMS_PER_WORKER`` per
worker in every pass) rendered by ``workers`` threads sharing one PathTracer, ``ITEMS_PER_STEP``
per worker between two looks at the commands. A command that changes the image also interrupts
the items in flight (``PathTracer.stop_flag``, read by the compiled bounce loop before every
bounce), so an edit waits for at most one bounce of one item.
"""
from __future__ import annotations

import math
import os
import time
import traceback
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .. import stats
from ..errors import LaminaError
from ..film import FilmAccumulator
from .frames import FrameWriter
from .protocol import END, PROTOCOL, CommandQueue, EventWriter, ProtocolError
from .state import SessionScene

LEVEL_PIXELS = 4096       # pixels of the first (smallest) reduced pass at most
LEVEL_STEP = 4            # each further reduced pass has LEVEL_STEP × the width and height
LANES_PER_ITEM = 1 << 14  # paths per work item (its fixed cost is ~0.1 ms: backend/render.py)
ITEMS_PER_WORKER = 2      # a pass is cut into at least this many items per worker (small ones too)
ITEMS_PER_STEP = 3        # items per worker rendered between two looks at the commands
FRAME_INTERVAL = 0.25     # seconds between frames of completed full-resolution passes (at least)
PARTIAL_INTERVAL = 0.5    # seconds between frames within one long pass
DEFAULT_SAMPLES = 32


def level_scales(width: int, height: int) -> list[int]:
    """Divisors of the reduced passes, coarsest first (empty if the image is already small)."""
    k = 1
    while math.ceil(width / k) * math.ceil(height / k) > LEVEL_PIXELS:
        k *= 2
    out = []
    while k > 1:
        out.append(k)
        k //= LEVEL_STEP
    return out


class Pass:
    """One pass: ``spp`` samples (indices sample0 …) in every pixel of a film of the given size."""

    def __init__(self, index: int, scale: int, width: int, height: int, crop, spp: int, sample0: int,
                 workers: int = 1):
        self.index, self.scale, self.width, self.height = index, scale, width, height
        self.spp, self.sample0 = spp, sample0
        x0, y0, x1, y1 = crop
        ys, xs = np.mgrid[y0:y1, x0:x1]
        pixels = (ys * width + xs).ravel().astype(np.int64)
        per_item = max(1, LANES_PER_ITEM // spp)
        # Even the first, smallest pass keeps every worker busy: its frame comes sooner with more
        # cores (the image does not depend on the cut: counter-based random numbers).
        n = max(1, math.ceil(pixels.size / per_item), min(ITEMS_PER_WORKER * workers, pixels.size))
        self.items = [band for band in np.array_split(pixels, n) if band.size]
        self.cursor = 0

    @property
    def finished(self) -> bool:
        return self.cursor >= len(self.items)


def scaled_crop(crop, width: int, height: int, scale: int):
    """The crop region (x0, y0, x1, y1, rows from the top) of a film 1/scale the size."""
    if crop is None:
        return 0, 0, math.ceil(width / scale), math.ceil(height / scale)
    x0, y0, x1, y1 = crop
    return x0 // scale, y0 // scale, max(math.ceil(x1 / scale), x0 // scale + 1), \
        max(math.ceil(y1 / scale), y0 // scale + 1)


class Progressive:
    """The rendering of one generation: its passes, films and frames."""

    def __init__(self, session: "Session", generation: int):
        self.session = session
        self.generation = generation
        # The film section as parsed (the scene's width and height change with every pass).
        self.width, self.height, _, self.crop, self.transparent = session.state.film
        self.scales = level_scales(self.width, self.height)
        self.started = time.perf_counter()
        self.film = FilmAccumulator(self.width, self.height)
        self.film.transparent = self.transparent
        self.level_film = None          # the last completed reduced pass
        self.level_scale = 1
        self.spp_done = 0
        self.passes_made = 0
        self.current: Pass | None = None
        self.current_film = None
        self.last_frame = 0.0
        self.frames = 0
        self.finished = False

    # -- planning

    def _next_pass(self) -> Pass | None:
        index = self.passes_made
        if index < len(self.scales):
            k = self.scales[index]
            w, h = math.ceil(self.width / k), math.ceil(self.height / k)
            p = Pass(index, k, w, h, scaled_crop(self.crop, self.width, self.height, k), 1, 0,
                     self.session.workers)
            film = FilmAccumulator(w, h)
            film.transparent = self.transparent
            self.current_film = film
        else:
            target = self.session.samples
            left = (target - self.spp_done) if target else 1 << 30
            if left <= 0:
                return None
            crop = scaled_crop(self.crop, self.width, self.height, 1)
            pixels = (crop[2] - crop[0]) * (crop[3] - crop[1])
            block = max(1, min(LANES_PER_ITEM * self.session.workers // max(pixels, 1), left, 64))
            p = Pass(index, 1, self.width, self.height, crop, block, self.spp_done, self.session.workers)
            self.current_film = self.film
        self.passes_made += 1
        return p

    # -- rendering

    def step(self) -> bool:
        """Render one round of items (ITEMS_PER_STEP per worker, taken by the workers as they
        finish: a slow item holds back only the end of the round). False once the target is
        reached."""
        if self.finished:
            return False
        if self.current is None or self.current.finished:
            self.current = self._next_pass()
            if self.current is None:
                self._finish()
                return False
        p = self.current
        first = p.index == 0          # the first pass always ends with a frame
        items = p.items[p.cursor:p.cursor + ITEMS_PER_STEP * self.session.workers]
        results = self.session.render_items(items, p, interruptible=not first, key=(self.generation, p.index))
        if results is None:                        # interrupted by a command: redo this round
            return True
        for band, result in zip(items, results):
            self.current_film.add(band, result)
        p.cursor += len(items)
        now = time.perf_counter()
        if p.finished:
            if p.scale > 1:
                self.level_film, self.level_scale = self.current_film, p.scale
                self._frame(p.scale, 1, final=False)
            else:
                self.spp_done += p.spp
                target = self.session.samples
                reached = bool(target) and self.spp_done >= target
                if reached:
                    self._finish()
                    return False
                if now - self.last_frame >= FRAME_INTERVAL or self.spp_done == p.spp:
                    self._frame(1, self.spp_done, final=False)
        elif now - self.last_frame >= PARTIAL_INTERVAL:
            if p.scale > 1:
                pass                               # reduced passes are short: whole frames only
            else:
                self._frame(1, self.spp_done, final=False)
        return True

    def _finish(self) -> None:
        self.finished = True
        self._frame(1, self.spp_done, final=True)
        self.session.events("idle", generation=self.generation, spp=self.spp_done,
                            seconds=round(time.perf_counter() - self.started, 3))

    # -- frames

    def image(self, scale: int) -> np.ndarray:
        """RGBA (height, width, 4) float32, row 0 at the top, of the reduced pass ``scale`` or
        of the full-resolution film (pixels it has not reached show the last reduced pass)."""
        if scale > 1:
            return _rgba(self.level_film, self.transparent, None)
        return _rgba(self.film, self.transparent, self._fallback())

    def _fallback(self):
        if self.level_film is None:
            return None
        low = _rgba(self.level_film, self.transparent, None)
        lw, lh = self.level_film.width, self.level_film.height
        xs = np.minimum(((np.arange(self.width) + 0.5) * lw / self.width).astype(np.int64), lw - 1)
        ys = np.minimum(((np.arange(self.height) + 0.5) * lh / self.height).astype(np.int64), lh - 1)
        up = low[ys][:, xs]
        if self.crop is None:
            return up
        # The reduced pass's crop is rounded outwards (scaled_crop): only pixels inside the
        # full-resolution crop take its values, the rest stay 0 (alpha 0) as in every frame.
        x0, y0, x1, y1 = self.crop
        out = np.zeros_like(up)
        out[y0:y1, x0:x1] = up[y0:y1, x0:x1]
        return out

    def _frame(self, scale: int, spp: int, final: bool) -> None:
        if scale == 1 and spp == 0 and self.level_film is None and not final:
            return
        session = self.session
        path, number = session.frames.write(self.image(scale), self.generation, spp, scale, final)
        extra = {}
        if final and scale == 1:
            # The denoising features of the final image (the viewport's Denoise, docs/session.md).
            with np.errstate(all="ignore"):
                features = np.concatenate([self.film.albedo_image(), self.film.normal_image()], axis=2)
            extra["features"] = str(session.frames.write_features(
                np.nan_to_num(features.astype(np.float32)), number, self.generation, spp))
        self.frames += 1
        self.last_frame = time.perf_counter()
        h, w = (self.level_film.height, self.level_film.width) if scale > 1 else (self.height, self.width)
        session.events("frame", generation=self.generation, frame=number, path=str(path), width=w, height=h,
                       spp=spp, scale=scale, final=final,
                       seconds=round(self.last_frame - self.started, 3), **extra)


def _rgba(film: FilmAccumulator, transparent: bool, fallback) -> np.ndarray:
    count = film.counts()
    rgb = film.combined()
    if transparent:
        alpha = film.coverage()
    else:
        alpha = (count > 0).astype(np.float64)
    out = np.concatenate([rgb, alpha[:, :, None]], axis=2).astype(np.float32)
    if fallback is not None:
        empty = count == 0
        out[empty] = fallback[empty]
    return out


class Session:
    def __init__(self, frame_dir, workers: int = 0, samples: int = DEFAULT_SAMPLES, events=None,
                 commands: CommandQueue | None = None, warm: bool = False):
        self.events = events or EventWriter()
        self.commands = commands or CommandQueue()
        self.frames = FrameWriter(frame_dir)
        self.workers = max(1, min(workers or os.cpu_count() or 1, 64))
        self.samples = samples
        self.state = SessionScene()
        self.state.on_event = lambda e: self.events(e.pop("event"), **e)
        self.generation = -1
        self.progress: Progressive | None = None
        self.error: str | None = None
        self.warm = warm
        self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="lamina-session") \
            if self.workers > 1 else None

    # -- rendering work items

    def render_items(self, items: list, p: Pass, interruptible: bool, key) -> list | None:
        from ..integrator import RenderInterrupted
        tracer = self.state.tracer
        scene = self.state.scene
        scene.width, scene.height = p.width, p.height
        tracer.interrupt = self.commands.restart_pending if interruptible else None
        tracer.stop_flag = getattr(self.commands, "restart_flag", None) if interruptible else None
        seed = int(scene.settings.seed)

        def one(args):
            i, band = args
            rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, *key, p.sample0, p.cursor + i])))
            try:
                return tracer.render(band, p.spp, rng, p.sample0)
            finally:
                stats.take()

        jobs = list(enumerate(items))
        try:
            if self._pool is None:
                results = [one(j) for j in jobs]
            else:
                futures = [self._pool.submit(one, j) for j in jobs]
                results, error = [], None
                for f in futures:
                    try:
                        results.append(f.result())
                    except BaseException as exc:  # noqa: BLE001 - re-raised below, after all finished
                        error = error or exc
                if error is not None:
                    raise error
        except RenderInterrupted:
            return None
        finally:
            tracer.interrupt = None
            tracer.stop_flag = None
        return results

    # -- commands

    def _handle(self, items: list) -> bool:
        """Apply waiting commands (all of them at once: edits coalesce into one rebuild).
        Returns False when the session must end."""
        keep_going = True
        scene_cmd = None
        changes: list[dict] = []
        generation = None
        for item in items:
            if item is END:
                return False
            if isinstance(item, ProtocolError):
                self.events("error", message=str(item), fatal=False)
                continue
            cmd = item["cmd"]
            if cmd == "stop":
                keep_going = False
                break
            if cmd == "ping":
                self.events("pong", id=item.get("id"))
            elif cmd == "samples":
                self.samples = item["samples"]
                if self.progress is not None and self.progress.finished and \
                        (self.samples == 0 or self.samples > self.progress.spp_done):
                    self.progress.finished = False       # more samples: continue accumulating
            elif cmd == "scene":
                scene_cmd, changes = item, []
                generation = self._generation(item, generation)
            elif cmd == "update":
                changes.append(item["changes"])
                generation = self._generation(item, generation)
        if scene_cmd is not None or changes:
            self._apply(scene_cmd, changes, generation)
        if self.progress is not None and self.samples and self.progress.spp_done >= self.samples \
                and not self.progress.finished and self.progress.passes_made > len(self.progress.scales):
            self.progress._finish()
        return keep_going

    def _generation(self, item: dict, current):
        g = item["generation"]
        if g < self.generation or (current is not None and g < current):
            self.events("warning", message=f"{item['cmd']}: generation {g} is older than "
                                           f"{max(self.generation, current or 0)}; frames keep the newer one")
            return max(self.generation, current or 0)
        return g

    def _apply(self, scene_cmd, changes: list, generation: int) -> None:
        t0 = time.perf_counter()
        self.generation = generation
        self.progress = None
        rebuilt: dict = {}
        try:
            if scene_cmd is not None:
                rebuilt.update(self.state.load(scene_cmd["scene"], scene_cmd.get("where", "<session scene>"),
                                               scene_cmd.get("base")))
            if changes:
                # All the batch's edits, then one build (a failing edit and its fix arrive together
                # when the artist corrects a field quickly: the fix must win).
                for part, seconds in self.state.update_all(changes).items():
                    rebuilt[part] = round(rebuilt.get(part, 0.0) + seconds, 4)
        except LaminaError as exc:
            self.error = str(exc)
            self.events("error", generation=generation, message=str(exc), fatal=False)
            return
        except Exception as exc:  # noqa: BLE001 - an input the loader did not foresee: not fatal
            # The half-built state is dropped: the next 'scene' starts clean.
            self.state = SessionScene()
            self.state.on_event = lambda e: self.events(e.pop("event"), **e)
            self.error = f"internal error while loading the scene: {type(exc).__name__}: {str(exc)[:200]}"
            self.events("error", generation=generation, message=self.error + " (send the scene again)",
                        fatal=False)
            return
        self.error = None
        for w in self.state.warnings:
            self.events("warning", generation=generation, message=w)
        s = self.state.scene
        self.events("updated", generation=generation, rebuilt=sorted(rebuilt), seconds=round(time.perf_counter() - t0, 4),
                    timings=rebuilt, width=s.width, height=s.height, triangles=int(s.soup.count))
        self.progress = Progressive(self, generation)

    # -- main loop

    def run(self) -> int:
        from ..warmup import ensure_compiled
        ensure_compiled(lambda e: self.events(e.pop("event"), **e))
        self.events("ready", protocol=PROTOCOL, pid=os.getpid(), workers=self.workers, samples=self.samples)
        if self.warm:
            self._warm_up()
        try:
            while True:
                busy = self.progress is not None and not self.progress.finished
                items = self.commands.take(block=not busy)
                if items and not self._handle(items):
                    break
                if self.progress is not None and not self.progress.finished:
                    self.progress.step()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True, cancel_futures=True)
        try:
            self.events("bye")
        except (OSError, ValueError):      # the client closed our stdout: nobody to tell
            pass
        return 0

    def _warm_up(self) -> None:
        """Load every compiled kernel now (a pre-started session waits for its scene with them
        loaded, so the first frame does not pay for it); skipped if a command is waiting."""
        if self.commands.restart_pending():
            return
        from ..warmup import load_kernels
        self.events("warm", seconds=round(load_kernels(), 3))


def run_session(frame_dir, workers: int = 0, samples: int = DEFAULT_SAMPLES, warm: bool = False) -> int:
    events = EventWriter()
    try:
        return Session(frame_dir, workers, samples, events, warm=warm).run()
    except LaminaError:
        raise
    except Exception as exc:  # noqa: BLE001 - reported as one event and one line, then status 1
        traceback.print_exc()
        message = f"internal error: {type(exc).__name__}: {exc}"
        try:
            events("error", message=message, fatal=True)
        except (OSError, ValueError):
            pass
        raise LaminaError(message) from None
