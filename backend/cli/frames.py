"""``render`` with several scene files: the frames of an animation (docs/cli.md, docs/cluster.md).

    python -m backend render shot_0001.json shot_0002.json ... -o out/frame_####.exr [--cluster ADDR]

Each frame is an ordinary render (render_one.render_scene) written as soon as it is done; ``####``
in ``-o`` (and ``--png``) becomes the frame number, zero-padded to the number of ``#``. The frame
number is the number that ends the scene file's name (``shot_0012.json`` → 12), or the position
on the command line (from 1) when a name has none or two names give the same.

Locally the frames render one after the other (each uses every core). On a cluster two frames are
in flight: while one frame's last work items run, the next frame's items keep the other workers
busy; the earlier frame's items have priority (cluster.ClusterItems). A frame that fails (a bad
scene file, a lost scheduler) is reported and the others still render; the exit status is then 2.
"""
from __future__ import annotations

import re
import signal
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ..errors import LaminaError
from . import render_one

FRAMES_IN_FLIGHT = 2       # on a cluster: the next frame fills the workers the current one leaves


def frame_numbers(scenes: list[Path]) -> list[int]:
    found = [re.search(r"(\d+)$", p.stem) for p in scenes]
    numbers = [int(m.group(1)) if m else None for m in found]
    if None in numbers or len(set(numbers)) != len(numbers):
        return list(range(1, len(scenes) + 1))
    return numbers


def frame_path(pattern: str, number: int, what: str) -> Path:
    """``pattern`` with its run of ``#`` replaced by ``number`` (zero-padded to its length)."""
    runs = re.findall(r"#+", pattern)
    if len(runs) != 1:
        raise LaminaError(f"{what} {pattern!r}: with several scene files it needs one run of # "
                          f"for the frame number, e.g. frame_####.exr")
    return Path(pattern.replace(runs[0], f"{number:0{len(runs[0])}d}"))


def render_frames(args, printer) -> int:
    scenes = [Path(s) for s in args.scene]
    try:
        if args.partial:
            raise LaminaError("--partial takes one scene file (it is the add-on's protocol)")
        numbers = frame_numbers(scenes)
        outputs = [frame_path(args.output, n, "-o") for n in numbers]
        pngs = [str(frame_path(args.png, n, "--png")) if args.png else None for n in numbers]
        for output, png in zip(outputs, pngs):
            render_one.check_outputs(output, png, None)
        address = args.cluster
        local = None
        if address:
            from ..cluster import CONNECT_TIMEOUT, connect, require_distributed
            require_distributed()
            # One local cluster for all frames, not one per frame; a scheduler that cannot be
            # reached is one error, not one per frame.
            local = connect(address, args.cluster_timeout or CONNECT_TIMEOUT)
            if address.startswith("local:"):
                address = local[1].scheduler_address
    except LaminaError as exc:
        if printer.mode == "json":
            printer.emit({"event": "error", "message": str(exc)})
        raise

    stop = threading.Event()
    active: set = set()
    lock = threading.Lock()

    def request_stop(*_):
        stop.set()
        with lock:
            for renderer in active:
                renderer.request_stop()

    signal.signal(signal.SIGINT, request_stop)
    signal.signal(signal.SIGTERM, request_stop)

    def one(k: int):
        if stop.is_set():
            return "skipped"
        frame = numbers[k]

        def emit(event):
            printer.emit({**event, "frame": frame})

        def started(renderer):
            with lock:
                active.add(renderer)
            if stop.is_set():
                renderer.request_stop()

        options = render_one.options_from_args(args)
        options.cluster = address
        options.cluster_priority = -k          # earlier frames first
        try:
            return render_one.render_scene(args, scenes[k], outputs[k], pngs[k], printer, emit,
                                           options, started)
        except LaminaError as exc:
            emit({"event": "error", "message": str(exc)})
            if printer.mode != "json":
                print(f"error: frame {frame} ({scenes[k]}): {exc}", file=sys.stderr)
            return "failed"

    in_flight = FRAMES_IN_FLIGHT if address else 1
    try:
        with ThreadPoolExecutor(in_flight, thread_name_prefix="lamina-frame") as pool:
            statuses = list(pool.map(one, range(len(scenes))))
    finally:
        if local is not None:
            from ..cluster import close_connection
            close_connection(*local)
    failed = [numbers[k] for k, s in enumerate(statuses) if s == "failed"]
    if failed:
        raise LaminaError(f"{len(failed)} of {len(scenes)} frame(s) failed: "
                          f"{', '.join(str(n) for n in failed[:20])}{' ...' if len(failed) > 20 else ''}")
    return 130 if stop.is_set() or any(s in (130, "skipped") for s in statuses) else 0
