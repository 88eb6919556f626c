"""Rendering on a Dask cluster (``render --cluster``, backend/cluster.py): a local cluster of two
worker processes gives the very image of a local render, also when a worker is killed halfway;
the scene's files are sent once (counted); an unreachable scheduler or a missing ``distributed``
is one clear line."""
import json
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from backend.imageio import read_exr, write_exr
from backend.render import Renderer, RenderOptions
from backend.scene.loader import load_scene
from conftest import DATA, ROOT
from render_util import IDENTITY, front_perspective, scene

distributed = pytest.importorskip("distributed")   # requirements-dev.txt pins it


def write_scene(folder: Path, spp: int = 16, camera_distance: float = 4.0, files: bool = True) -> Path:
    """A scene that reads three kinds of files: a mesh (.npz), an environment map (.exr) and an
    IES profile, in sub-folders, named by relative paths (``files=False``: the document only)."""
    if files:
        (folder / "meshes").mkdir(parents=True, exist_ok=True)
        (folder / "maps").mkdir(exist_ok=True)
        positions = np.array([[-2, -2, -1], [2, -2, -1], [2, 2, -1], [-2, 2, -1]], dtype=np.float64)
        np.savez(folder / "meshes" / "floor.npz", positions=positions, indices=np.array([[0, 1, 2], [0, 2, 3]]))
        sky = np.linspace(0.2, 1.0, 16 * 8 * 3, dtype=np.float32).reshape(8, 16, 3)
        write_exr(folder / "maps" / "sky.exr", {"": sky})
        shutil.copy(DATA / "ies" / "erco_defined_spot_lm95.ies", folder / "maps" / "spot.ies")
    light = {"type": "point", "power": 200.0, "color": [1, 1, 1],
             "to_world": [[1, 0, 0, 0], [0, 1, 0, -1], [0, 0, 1, 2], [0, 0, 0, 1]],
             "ies": {"file": "maps/spot.ies"}}
    data = scene(48, 48, front_perspective(camera_distance, 0.4),
                 {"m": {"type": "diffuse", "color": 0.7}},
                 {"floor": {"file": "meshes/floor.npz"},
                  "ball": {"shape": "sphere", "radius": 0.8, "segments": 24}},
                 [{"mesh": "floor", "materials": ["m"]},
                  {"mesh": "ball", "materials": ["m"], "to_world": IDENTITY}],
                 lights=[light], world={"type": "environment", "file": "maps/sky.exr", "strength": 0.5},
                 render={"spp": spp, "max_bounces": 3, "seed": 7})
    path = folder / "scene.json"
    path.write_text(json.dumps(data))
    return path


def render(path: Path, **options):
    sc = load_scene(path)
    opts = RenderOptions(**options)
    opts.apply(sc)
    result = Renderer(sc, str(path), opts).run()
    assert result.error is None, result.error
    return result


def same_image(a, b) -> bool:
    return (np.array_equal(a.film.sum, b.film.sum) and np.array_equal(a.film.sum_sq, b.film.sum_sq)
            and np.array_equal(a.film.count, b.film.count))


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A local cluster of 2 worker processes (1 thread each). The workers inherit the fault
    folder (backend/work_items.py, _injected_fault) and a fresh file cache from this environment."""
    root = tmp_path_factory.mktemp("cluster")
    faults, cache = root / "faults", root / "worker-cache"
    faults.mkdir()
    saved = {k: os.environ.get(k) for k in ("LAMINA_TEST_FAULT_DIR", "LAMINA_CLUSTER_CACHE")}
    os.environ["LAMINA_TEST_FAULT_DIR"] = str(faults)
    os.environ["LAMINA_CLUSTER_CACHE"] = str(cache)
    import logging
    local = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                     dashboard_address=None, silence_logs=logging.CRITICAL)
    try:
        yield local.scheduler_address, faults, root
    finally:
        local.close()
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@pytest.fixture(scope="module")
def reference(cluster):
    """The scene and its local render (threads of this process)."""
    path = write_scene(cluster[2] / "scene")
    return path, render(path, workers=2)


def test_cluster_render_is_bit_identical_and_sends_files_once(cluster, reference):
    address = cluster[0]
    path, local = reference
    first = render(path, cluster=address)
    assert same_image(first, local)
    files = sorted(p.name for p in (cluster[2] / "scene").rglob("*") if p.is_file())
    assert files == ["floor.npz", "scene.json", "sky.exr", "spot.ies"]
    size = sum(p.stat().st_size for p in (cluster[2] / "scene").rglob("*") if p.is_file())
    # Both workers use one cache folder (one machine): every file is sent once, whole.
    assert first.stats["cluster_scene_files_sent"] == 4
    assert first.stats["cluster_scene_bytes_sent"] == size
    again = render(path, cluster=address)
    assert same_image(again, local)
    assert again.stats["cluster_scene_files_sent"] == 0
    assert again.stats["cluster_scene_bytes_sent"] == 0
    # The next frame (another camera, same files): only the scene document travels.
    frame2 = write_scene(cluster[2] / "scene", camera_distance=4.5, files=False)
    moved = render(frame2, cluster=address)
    assert moved.stats["cluster_scene_files_sent"] == 1
    assert moved.stats["cluster_scene_bytes_sent"] == frame2.stat().st_size
    write_scene(cluster[2] / "scene", files=False)         # back to the reference's document for later tests


def test_a_local_cluster_of_three_workers_gives_the_same_image(reference):
    # `--cluster local:3`: a cluster this render starts and ends itself, 3 worker processes.
    path, local = reference
    assert same_image(render(path, cluster="local:3"), local)


def test_shared_files_send_only_the_document(cluster, tmp_path):
    """--cluster-files shared: the workers read the master's paths (one machine here)."""
    path = write_scene(tmp_path / "shared", spp=4)
    local = render(path, workers=1)
    shared = render(path, cluster=cluster[0], cluster_files="shared")
    assert same_image(shared, local)
    assert shared.stats["cluster_scene_files_sent"] == 1
    assert shared.stats["cluster_scene_bytes_sent"] == path.stat().st_size


def test_user_preset_with_a_texture_reaches_workers_that_lack_it(cluster, tmp_path, monkeypatch):
    """A material named by a preset from a folder only this process knows (LAMINA_PRESET_PATH,
    set after the workers started), whose colour is a texture next to the preset: the workers
    get the preset document and its texture and use them under the master's paths."""
    folder = tmp_path / "my-presets"
    (folder / "textures").mkdir(parents=True)
    ramp = np.linspace(0.1, 0.9, 8 * 8 * 3, dtype=np.float32).reshape(8, 8, 3)
    write_exr(folder / "textures" / "ramp.exr", {"": ramp})
    (folder / "cluster-test-ramp.json").write_text(json.dumps(
        {"format": "lamina-preset", "version": 1, "name": "cluster-test-ramp",
         "material": {"type": "diffuse", "color": {"texture": "textures/ramp.exr"}}}))
    monkeypatch.setenv("LAMINA_PRESET_PATH", str(folder))
    data = scene(32, 32, front_perspective(4.0, 0.3), {"m": "cluster-test-ramp"},
                 {"ball": {"shape": "sphere", "radius": 1.0, "segments": 24}},
                 [{"mesh": "ball", "materials": ["m"]}],
                 world={"type": "constant", "color": [0.5, 0.5, 0.5], "strength": 1.0},
                 render={"spp": 4, "max_bounces": 2, "seed": 3})
    path = tmp_path / "preset-scene.json"
    path.write_text(json.dumps(data))
    local = render(path, workers=1)
    remote = render(path, cluster=cluster[0])
    assert same_image(remote, local)
    assert remote.stats["cluster_scene_files_sent"] == 3        # document, preset, texture


def test_workers_with_another_renderer_are_refused(cluster, reference, monkeypatch):
    """Their samples would differ: the render does not start, the error names a worker."""
    from backend.errors import LaminaError
    from backend.kernels import cache
    monkeypatch.setattr(cache, "source_key", lambda: "edited-kernels")     # on this side only
    with pytest.raises(LaminaError, match=r"the cluster worker at tcp://\S+ runs another version"):
        render(reference[0], cluster=cluster[0])


def test_adaptive_sampling_and_time_limit_work_the_same_on_the_cluster(cluster, reference):
    """Adaptive rounds are planned from the merged image, so the cluster stops the same pixels
    at the same rounds; a time limit stops after the first full pass."""
    address = cluster[0]
    path, _ = reference
    # 96 × 96 px: 28 samples per pixel per round, so the 56 spp take two rounds.
    adaptive = dict(spp=56, noise_target=0.1, min_spp=8, resolution=(96, 96))
    local = render(path, workers=2, **adaptive)
    remote = render(path, cluster=address, **adaptive)
    counts = local.film.count
    assert counts.min() < counts.max() == 56                 # some pixels stopped early
    assert same_image(remote, local)
    limited = render(path, cluster=address, spp=100000, time_limit=0.5)
    assert not limited.interrupted and 1 <= limited.spp_done < 100000
    assert limited.film.count.min() >= 1


def test_package_loads_from_the_cache_alone(tmp_path, monkeypatch):
    """No shared file system: what a worker loads comes from its cache only. The scene is named
    by a relative path (from its folder), the original folder is gone when the package loads."""
    from backend import cluster_files
    folder = tmp_path / "project"
    write_scene(folder)
    monkeypatch.chdir(folder)
    monkeypatch.setenv("LAMINA_CLUSTER_CACHE", str(tmp_path / "cache"))
    master = load_scene("scene.json")
    package, blobs = cluster_files.make_package(master, "scene.json")
    for digest, suffix in package.hashes().items():
        cluster_files.store(digest, suffix, cluster_files.blob_bytes(blobs[digest]))
    monkeypatch.chdir(tmp_path)
    folder.rename(tmp_path / "moved-away")
    worker = cluster_files.load_package(package)
    assert np.array_equal(worker.soup.vertices, master.soup.vertices) and worker.width == master.width
    assert sorted(Path(p).name for p in master.inputs["files"]) == ["floor.npz", "sky.exr", "spot.ies"]


def test_worker_killed_mid_render_gives_the_identical_image(cluster, reference):
    address, faults, _ = cluster
    path, local = reference
    (faults / "kill-1").write_text("")          # the first item to take it SIGKILLs its worker
    warnings = []
    sc = load_scene(path)
    opts = RenderOptions(cluster=address)
    opts.apply(sc)
    renderer = Renderer(sc, str(path), opts,
                        lambda e: warnings.append(e["message"]) if e["event"] == "warning" else None)
    result = renderer.run()
    assert not (faults / "kill-1").exists(), "the fault was not taken"
    assert result.error is None and not result.interrupted
    assert same_image(result, local)
    assert any("left during the render" in w and "unaffected" in w for w in warnings), warnings


def test_worker_lacking_files_asks_for_them(cluster, reference, monkeypatch):
    """A worker that joined after the files were sent (here: no files are sent up front) raises
    MissingSceneFiles from its task; the master sends them to it and resubmits the item."""
    from backend.cluster import ClusterItems
    address = cluster[0]
    render(reference[0], cluster=address)                  # the workers hold the scene's files
    shutil.copytree(cluster[2] / "scene", cluster[2] / "late")
    path = write_scene(cluster[2] / "late", spp=8, files=False)     # same files, a new document
    local = render(path, workers=1)
    original = ClusterItems._send_files
    calls = []

    def lazy(self, workers):
        calls.append(workers)
        if workers is not None:                              # only on a task's request
            original(self, workers)
    monkeypatch.setattr(ClusterItems, "_send_files", lazy)
    result = render(path, cluster=address)
    assert same_image(result, local)
    assert calls[0] is None and len(calls) >= 2
    assert result.stats["cluster_scene_files_sent"] == 1     # the new document; the rest is cached
    assert result.stats["cluster_scene_bytes_sent"] == path.stat().st_size


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_scheduler_is_one_clear_line(tmp_path):
    path = write_scene(tmp_path)
    address = f"tcp://127.0.0.1:{_free_port()}"
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(path), "-o", str(tmp_path / "o.exr"),
                           "--cluster", address, "--cluster-timeout", "1"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"error: cannot reach the Dask scheduler at {address} within 1 s "
        f"(Timed out trying to connect to {address} after 1 s); is `dask scheduler` running there, "
        f"and the port open?"]
    assert not (tmp_path / "o.exr").exists()


def test_missing_distributed_is_one_clear_line(tmp_path):
    path = write_scene(tmp_path)
    # Runs the CLI with `distributed` made unimportable, as in an install without it.
    code = ("import sys\n"
            "class Block:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name == 'distributed' or name.startswith('distributed.'):\n"
            "            raise ImportError('No module named ' + repr(name))\n"
            "sys.meta_path.insert(0, Block())\n"
            "from backend.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    proc = subprocess.run([sys.executable, "-c", code, "render", str(path), "-o", str(tmp_path / "o.exr"),
                           "--cluster", "local:2"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --cluster needs Dask's 'distributed' package"), proc.stderr
    assert "pip install distributed==" in lines[0]


def test_cli_local_cluster_json_progress_and_same_exr(tmp_path, reference):
    path, local = reference
    out = tmp_path / "cluster.exr"
    env = dict(os.environ, LAMINA_CLUSTER_CACHE=str(tmp_path / "cache"))
    env.pop("LAMINA_TEST_FAULT_DIR", None)
    proc = subprocess.run([sys.executable, "-m", "backend", "render", str(path), "-o", str(out),
                           "--cluster", "local:2", "--progress", "json"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr
    events = [json.loads(line) for line in proc.stdout.splitlines()]
    assert events[0]["event"] == "start" and events[0]["parallel"] == "cluster"
    assert events[0]["workers"] == 2 and events[0]["cluster"] == "local:2"
    fractions = [e["fraction"] for e in events if e["event"] == "progress"]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert events[-1]["event"] == "done" and events[-1]["spp"] == 16
    pixels, names = read_exr(out)
    rgb = pixels[:, :, [names.index(c) for c in "RGB"]]
    assert np.array_equal(rgb, local.film.combined().astype(np.float32))


def _dask(*args, env=None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "dask", *args], cwd=ROOT, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _end(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)


def test_scheduler_lost_mid_render_is_an_error_and_the_partial_image_is_written(tmp_path):
    """A `dask scheduler` and a `dask worker` started as a user would (docs/cluster.md); the
    scheduler is killed once the render has merged its first pass."""
    path = write_scene(tmp_path / "scene", spp=256)
    address = f"tcp://127.0.0.1:{_free_port()}"
    env = dict(os.environ, PYTHONPATH=str(ROOT), LAMINA_CLUSTER_CACHE=str(tmp_path / "cache"))
    env.pop("LAMINA_TEST_FAULT_DIR", None)
    scheduler = _dask("scheduler", "--host", "127.0.0.1", "--port", address.rsplit(":", 1)[1],
                      "--no-dashboard", env=env)
    worker = None
    render_proc = None
    try:
        worker = _dask("worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard", env=env)
        out = tmp_path / "out.exr"
        render_proc = subprocess.Popen(
            [sys.executable, "-m", "backend", "render", str(path), "-o", str(out), "--resolution", "96x96",
             "--cluster", address, "--cluster-timeout", "20", "--progress", "json"],
            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        events = []
        for line in render_proc.stdout:
            events.append(json.loads(line))
            if events[-1]["event"] == "progress" and events[-1]["done"] >= 1:
                scheduler.kill()
                break
        stdout, stderr = render_proc.communicate(timeout=120)
        events += [json.loads(line) for line in stdout.splitlines()]
        assert render_proc.returncode == 2, stderr
        assert events[-1]["event"] == "error"
        lines = stderr.strip().splitlines()
        assert len(lines) == 1, stderr                        # one line, no Dask traceback
        assert lines[0].startswith(f"error: lost the connection to the Dask scheduler at {address}")
        assert lines[0].endswith(f"{out} holds the samples done before that")
        pixels, names = read_exr(out)
        samples = pixels[:, :, names.index("samples.Y")]
        assert 1 <= samples.min() and samples.max() < 256     # the passes merged before the loss
    finally:
        for proc in (render_proc, worker, scheduler):
            if proc is not None:
                _end(proc)


def test_cli_frames_of_an_animation_on_the_cluster(cluster, reference, tmp_path):
    """Several scene files: each frame written to its own EXR (#### = the number ending the
    file's name), each bit-identical to its local render."""
    address = cluster[0]
    folder = tmp_path / "shot"
    shutil.copytree(cluster[2] / "scene", folder)
    scenes, locals_ = [], []
    for number, distance in ((7, 4.0), (8, 4.3), (9, 4.6)):
        path = write_scene(folder, camera_distance=distance, files=False).rename(folder / f"shot_{number:04d}.json")
        scenes.append(path)
        locals_.append(render(path, workers=2))
    env = dict(os.environ)
    env.pop("LAMINA_TEST_FAULT_DIR", None)
    proc = subprocess.run([sys.executable, "-m", "backend", "render", *map(str, scenes),
                           "-o", str(tmp_path / "out" / "frame_####.exr"), "--cluster", address,
                           "--progress", "json"], cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr
    events = [json.loads(line) for line in proc.stdout.splitlines()]
    done = {e["frame"]: e for e in events if e["event"] == "done"}
    assert sorted(done) == [7, 8, 9]
    for number, local in zip((7, 8, 9), locals_):
        out = tmp_path / "out" / f"frame_{number:04d}.exr"
        assert done[number]["path"] == str(out.resolve())
        pixels, names = read_exr(out)
        rgb = pixels[:, :, [names.index(c) for c in "RGB"]]
        assert np.array_equal(rgb, local.film.combined().astype(np.float32)), number


def test_ctrl_c_cancels_and_writes_what_is_done(cluster, reference, tmp_path):
    import signal
    import time
    address = cluster[0]
    path, _ = reference
    out = tmp_path / "stopped.exr"
    env = dict(os.environ)
    env.pop("LAMINA_TEST_FAULT_DIR", None)
    proc = subprocess.Popen([sys.executable, "-m", "backend", "render", str(path), "-o", str(out),
                             "--spp", "100000", "--cluster", address, "--progress", "json"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for line in proc.stdout:
            event = json.loads(line)
            if event["event"] == "progress" and event["done"] >= 1:
                break
        t0 = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
        stopped_in = time.perf_counter() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert stopped_in < 10.0
    done = json.loads(stdout.splitlines()[-1])
    assert done["event"] == "done" and done["interrupted"] and 1 <= done["spp"] < 100000
    pixels, names = read_exr(out)
    assert pixels[:, :, names.index("samples.Y")].min() >= 1
    # The cluster is free again: none of the render's tasks is left on the scheduler.
    with distributed.Client(address, timeout=10) as client:
        left = client.run_on_scheduler(
            lambda dask_scheduler: [k for k in dask_scheduler.tasks if str(k).startswith("lamina-")])
    assert left == []
