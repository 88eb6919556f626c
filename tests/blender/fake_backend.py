"""A stand-in for ``python -m backend render`` speaking the JSON progress protocol (docs/cli.md).

Used as the add-on's "Backend Python" preference to test the engine's plumbing independently
of the renderer: FAKE_MODE = pixels | compiling | error | crash | crash_after_partial | hang. ``pixels`` writes a known image
(red = x + 1000·y from the top-left, so orientation errors are visible; green = the scene's seed,
or 0.5 for seed 0) and AOVs.
``hang`` starts two worker processes, ignores SIGTERM and reports progress forever: only a
process-group kill ends it. FAKE_PIDS names a file that receives every PID started.
"""
import json
import multiprocessing
import os
import signal
import sys
import time

import numpy as np


def worker():
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    while True:
        time.sleep(0.05)


def start_time(pid):
    """Kernel start time (identifies a process together with its PID; PIDs get reused)."""
    with open(f"/proc/{pid}/stat") as f:
        return int(f.read().rsplit(")", 1)[1].split()[19])


def emit(**event):
    sys.stdout.write(json.dumps(event) + "\n")
    sys.stdout.flush()


def main(argv):
    assert argv[:3] == ["-m", "backend", "render"], argv
    scene_path = argv[3]
    partial = argv[argv.index("--partial") + 1]
    scene = json.load(open(scene_path))
    film = scene["film"]
    seed = scene.get("render", {}).get("seed", 0)
    w, h = film["width"], film["height"]
    mode = os.environ.get("FAKE_MODE", "pixels")
    if os.environ.get("FAKE_ARGV"):                  # the command line the engine built
        with open(os.environ["FAKE_ARGV"], "w") as f:
            json.dump(argv, f)
    pids = [os.getpid()]
    if mode == "compiling":                          # a cold kernel cache, then pixels
        emit(event="compiling", message="compiling render kernels (first run only) ...")
        emit(event="compiled", seconds=12.3, message="compiled render kernels in 12.3 s (cached in /x)")
        mode = "pixels"
    emit(event="start", width=w, height=h, spp=4, workers=1)
    if mode == "error":
        emit(event="error", message="scene.json: textures/broken.png: cannot read image (fake)")
        print("error: scene.json: textures/broken.png: cannot read image (fake)", file=sys.stderr)
        return 2
    if mode == "crash":
        raise ZeroDivisionError("fake crash in the renderer")
    if mode == "hang":
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        ctx = multiprocessing.get_context("spawn")
        procs = [ctx.Process(target=worker, daemon=False) for _ in range(2)]
        for p in procs:
            p.start()
        pids += [p.pid for p in procs]
        with open(os.environ["FAKE_PIDS"], "w") as f:
            json.dump([[pid, start_time(pid)] for pid in pids], f)
        i = 0
        while True:
            i += 1
            emit(event="progress", done=i, total=10 ** 6, fraction=i / 10 ** 6, elapsed=i * 0.05,
                 eta=1e5, samples_per_second=1.0)
            time.sleep(0.05)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    green = np.full_like(x, 0.5 if seed == 0 else float(seed))      # echoes the seed (animation test)
    rgba = np.stack([x + 1000 * y, green, np.full_like(x, 0.25), np.ones_like(x)], axis=2)
    aovs = np.stack([np.full_like(x, 0.1), np.full_like(x, 0.2), np.full_like(x, 0.3),
                     np.zeros_like(x), np.zeros_like(x), np.ones_like(x)], axis=2)
    for spp in (1, 2, 4):
        emit(event="progress", done=spp, total=4, fraction=spp / 4, elapsed=0.01 * spp, eta=0.0,
             samples_per_second=1.0)
    np.save(partial + ".tmp.npy", rgba)
    os.replace(partial + ".tmp.npy", partial)
    emit(event="partial", path=partial, spp=4)
    if mode == "crash_after_partial":                # e.g. out of memory 20 minutes into a render
        raise MemoryError("fake crash after a partial result")
    base = partial[:-4] if partial.endswith(".npy") else partial
    np.save(base + ".aovs.npy", aovs)
    emit(event="warning", message="fake warning from the renderer")
    emit(event="done", path=argv[argv.index("-o") + 1], elapsed=0.05, spp=4)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
