"""The compiled-kernel infrastructure: counter-based random numbers, images that do not depend on
how the work is cut, the kernel cache (keyed by version, announced once) and a clear error when
Numba is missing."""
from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats as sps

from backend.kernels import cache
from backend.kernels.rng import fill_uniform
from first_run import RECORD, cli, first_render, mixed_scene
from render_util import render

ROOT = Path(__file__).resolve().parent.parent


# --------------------------------------------------------------------------- random numbers

def _numbers(n=200_000, dims=24, seed=7, pixel_stride=1):
    pixels = (np.arange(n, dtype=np.int64) // 16) * pixel_stride
    samples = np.arange(n, dtype=np.int64) % 16
    out = np.empty((n, dims))
    fill_uniform(np.uint64(seed), pixels, samples, 0, out)
    return out


def test_uniform_numbers_are_uniform_and_pairwise_independent():
    u = _numbers()
    assert u.min() >= 0.0 and u.max() < 1.0
    # 1-D: chi-square over 64 bins for every dimension (Šidák-corrected level for 24 tests).
    level = 1 - (1 - 0.01) ** (1 / 30)
    for d in range(u.shape[1]):
        counts = np.bincount((u[:, d] * 64).astype(int), minlength=64)
        assert sps.chisquare(counts).pvalue > level, d
    # 2-D: neighbouring and distant dimension pairs, 16×16 cells.
    for a, b in [(0, 1), (4, 5), (3, 17), (10, 23), (2, 6), (5, 11)]:
        cells = (u[:, a] * 16).astype(int) * 16 + (u[:, b] * 16).astype(int)
        counts = np.bincount(cells, minlength=256)
        assert sps.chisquare(counts).pvalue > level, (a, b)


def test_numbers_depend_on_every_key_and_nothing_else():
    a = _numbers(4096, 4)
    assert np.array_equal(a, _numbers(4096, 4))                      # deterministic
    assert not np.any(a == _numbers(4096, 4, seed=8))                # seed
    assert not np.any(a[16:] == _numbers(4096, 4, pixel_stride=3)[16:])  # pixel (0·3 = 0)
    # Adjacent samples of a pixel and adjacent pixels are uncorrelated.
    u = _numbers(100_000, 2)
    r = np.corrcoef(u[:-1, 0], u[1:, 0])[0, 1]
    assert abs(r) < 4 / np.sqrt(u.shape[0])
    assert len(np.unique(u[:, 0])) == u.shape[0]                     # no repeats in 1e5


# --------------------------------------------------------------------------- determinism

_mixed_scene = mixed_scene


def _same(a, b):
    return (np.array_equal(a.film.sum, b.film.sum) and np.array_equal(a.film.sum_sq, b.film.sum_sq)
            and np.array_equal(a.film.count, b.film.count) and np.array_equal(a.film.albedo, b.film.albedo))


def test_same_image_whatever_the_worker_count_parallel_mode_or_batch_size(monkeypatch):
    data = _mixed_scene()
    base = render(data, workers=1)
    assert base.film.combined().mean() > 0
    for workers in (2, 3, 16):              # 16: more threads than this machine's cores and items in flight
        assert _same(base, render(data, workers=workers, parallel="threads")), workers
    for workers in (2, 3):
        assert _same(base, render(data, workers=workers, parallel="processes")), workers
    # Tiny work items: 12 rounds of one sample each instead of one round of 12.
    import backend.render as r
    monkeypatch.setattr(r, "LANES_PER_ITEM", 64)
    small = render(data, workers=1)
    assert _same(base, small)
    other_seed = copy.deepcopy(data)
    other_seed["render"]["seed"] = 4
    assert not np.array_equal(base.film.sum, render(other_seed, workers=1).film.sum)


# --------------------------------------------------------------------------- kernel cache

def test_cache_folder_is_keyed_by_sources_and_versions(tmp_path, monkeypatch):
    fake = tmp_path / "backend"
    (fake / "kernels").mkdir(parents=True)
    src = fake / "kernels" / "k.py"
    src.write_text("from numba import njit\n@njit\ndef f(x):\n    return x\n")
    (fake / "plain.py").write_text("x = 1\n")
    monkeypatch.setattr(cache, "BACKEND", fake)
    k1 = cache.source_key()
    (fake / "plain.py").write_text("x = 2\n")            # not compiled code: same key
    assert cache.source_key() == k1
    src.write_text(src.read_text() + "\n# changed\n")    # a kernel source changed
    k2 = cache.source_key()
    assert k2 != k1
    helper = fake / "kernels" / "helper.py"              # kernels/jit.py decorators: no "njit"
    helper.write_text("from .jit import kernel\n@kernel\ndef g(x):\n    return x\n")
    k3 = cache.source_key()
    assert k3 != k2
    helper.write_text(helper.read_text() + "\n# changed\n")
    assert cache.source_key() != k3
    k2 = cache.source_key()
    import numba
    monkeypatch.setattr(numba, "__version__", "0.0.0-other")
    assert cache.source_key() != k2                      # another Numba: another folder
    monkeypatch.setenv("LAMINA_KERNEL_CACHE", str(tmp_path / "c"))
    assert cache.user_cache_root() == tmp_path / "c"


_cli = cli


def test_first_run_compiles_once_and_says_so(tmp_path):
    """The first run on a cold cache compiles every kernel once and says so; the next one loads.
    On a cold session cache the first run is the one tests/first_run.py made before the first
    test (the compile the whole session uses); else it compiles into a folder of its own."""
    if RECORD:
        first, env, root, path = RECORD["first"], RECORD["env"], RECORD["root"], RECORD["scene"]
    else:
        root = tmp_path / "kernels"
        first, env, path = first_render(tmp_path, root)
    assert first.returncode == 0, first.stderr
    assert first.stderr.count("compiling render kernels (first run only)") == 1
    assert "compiled render kernels in" in first.stderr
    if (os.cpu_count() or 1) >= 2:
        # The layered lane was compiled by the second process (kernels/precompile.py) for the
        # argument types the shading kernel passes (kernels/precompile.layered_lane_signature): this
        # process loaded it from the cache and did not compile it again.
        log = [line for line in first.stdout.splitlines() if "batch.shade_lane" in line]
        assert any("data loaded from" in line for line in log), log
        assert not any("data saved to" in line for line in log), log
    second = _cli(["render", str(path), "-o", str(tmp_path / "b.exr"), "--workers", "1"], env)
    assert second.returncode == 0, second.stderr
    assert "compiling" not in second.stderr
    if not RECORD:
        folders = [p for p in root.iterdir() if p.is_dir()]
        assert folders == [root / cache.source_key()]
    folder = root / cache.source_key()
    assert (folder / "warm").exists()
    assert any(folder.rglob("*.nbi"))                  # Numba's index files are there


_LOADER_PROBE = """
import hashlib, json, sys
from backend import warmup
from backend.kernels import cache
cache.configure()
if sys.argv[1] == "numba":        # Numba's own loader (refreshes its compiler set-up first)
    from numba.core import caching
    caching.Cache.load_overload = cache._STATE["numba_load_overload"]
    from numba.core import codegen
    codegen.CPUCodeLibrary._unserialize, codegen.CPUCodeLibrary._get_module_for_linking = \
        cache._STATE["numba_library_load"]
warmup.ensure_compiled()
from render_util import render
data = json.loads(open(sys.argv[2]).read())
res = render(data, workers=1)
from backend.kernels.item_loop import run_item
unparsed = getattr(next(iter(run_item.overloads.values())).library, "_lamina_bitcode", None) is not None
print(hashlib.sha256(res.film.sum.tobytes()).hexdigest(), "numba.np.linalg" in sys.modules, unparsed)
"""


def test_warm_cache_loads_kernels_without_numba_compiler_set_up(tmp_path):
    """A process that finds its kernels cached loads them without Numba's compiler set-up (its
    target-context refresh: every lowering registry, SciPy's BLAS; 0.2–0.3 s of a material
    preview) and without parsing their bitcode (on ELF platforms), and renders the same image,
    bit for bit, as with Numba's own loader."""
    path = tmp_path / "s.json"
    path.write_text(json.dumps(_mixed_scene(spp=2)))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]))
    out = {}
    for loader in ("warm-up", "lean", "numba"):   # the first run compiles if the cache is cold
        r = subprocess.run([sys.executable, "-c", _LOADER_PROBE, loader, str(path)], capture_output=True,
                           text=True, env=env, cwd=ROOT)
        assert r.returncode == 0, r.stderr
        out[loader] = r.stdout.split()
    assert out["lean"][0] == out["numba"][0]
    assert out["lean"][1] == "False"       # the refresh (which imports numba.np.linalg) did not run
    assert out["numba"][1] == "True"       # ... and it is what Numba's own loader would run
    if sys.platform.startswith("linux"):
        assert out["lean"][2] == "True"    # the shading kernel's bitcode was never parsed
    assert out["numba"][2] == "False"


def test_missing_numba_is_one_clear_error(tmp_path):
    path = tmp_path / "s.json"
    path.write_text(json.dumps(_mixed_scene(spp=1)))
    code = ("import sys; sys.modules['numba'] = None; from backend.cli import main; "
            f"sys.exit(main(['render', {str(path)!r}, '-o', {str(tmp_path / 'o.exr')!r}]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in out.stderr, out.stderr
    assert "need Numba" in lines[0] and "numba==0.68.1" in lines[0]
    assert not (tmp_path / "o.exr").exists()


# --------------------------------------------------------------------------- kernels/jit.py

def test_kernel_decorators_compile_one_version_per_type_and_inline_only_what_they_mark(tmp_path):
    # In a fresh process with an empty cache, so that everything compiles (a cached caller would
    # not compile its callees at all).
    code = """
import kernel_jit_cases as c
assert c.two_constants(1.5) == 7.5
# Constants passed between kernels are not literal types: one version for (float64, int64).
assert [tuple(map(str, s)) for s in c.scale.signatures] == [("float64", "int64")], c.scale.signatures
assert [tuple(map(str, s)) for s in c.scale_inlined.signatures] == [("float64", "int64")]
# forceinline is the decorator's, never inherited from an inlined caller.
inline = {n: next(iter(f.overloads.values())).fndesc.inline
          for n, f in (("scale", c.scale), ("scale_inlined", c.scale_inlined))}
assert inline == {"scale": False, "scale_inlined": True}, inline
print("ok")
"""
    env = dict(os.environ, LAMINA_KERNEL_CACHE=str(tmp_path),
               PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]))
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-2000:]

