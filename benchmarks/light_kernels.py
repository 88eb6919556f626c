"""Compile time and per-lane cost of the compiled light kernels (backend/kernels/lights/).

    .venv/bin/python -m benchmarks.light_kernels [--lanes 1000000] [--repeat 3]
    .venv/bin/python -m benchmarks.light_kernels --compile     # cold: empties the kernel cache first

Per-lane cost: ``dispatch.sample`` for each light kind through the batch loop (kernels/lights/
batch.py), on ``--lanes`` shading points spread through a 3 m box around the lights, one light
for every lane; plus ``select`` (local selection) over the 10 lights of that table and over 64
lights, and ``pdf_hit`` / ``pdf_escaped``. Best of ``--repeat`` runs, CPU ns per lane (process
time: the figures hold on a shared machine), one thread.

Compile: the light batch entry points plus one probe kernel that calls every dispatch function
once per lane (what an integrator kernel that calls them compiles), from an empty cache folder
(``backend.kernels.cache.configure()``'s folder is deleted first), then again from the cache in a
fresh process; wall and CPU seconds (CPU is the figure that holds on a shared machine).
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time

import numpy as np


def mixed_lights():
    """One light of each kind (the test scene of tests/test_lights_kernel_table.py)."""
    from pathlib import Path

    from backend.ies.light import IESEmission
    from backend.ies.profile import IESProfile
    from backend.lights.area import AreaLight, CollimatedAreaLight
    from backend.lights.environment import ConstantWorld, EnvironmentMap
    from backend.lights.mesh import MeshLight
    from backend.lights.point import PointLight
    from backend.lights.profiles import SmoothCone
    from backend.lights.spot import SpotLight
    from backend.lights.sun import SunLight
    from backend.textures import ImageParam

    def tr(x, y, z):
        m = np.eye(4)
        m[:3, 3] = (x, y, z)
        return m

    rng = np.random.default_rng(5)
    ies = Path(__file__).resolve().parent.parent / "tests" / "data" / "ies" / "hew_overhead_quad90_8lamps_lm95.ies"
    # 2000 textured emitter triangles (a 40 × 25 grid of quads at z = 2.5)
    gx, gy = np.meshgrid(np.linspace(-1, 1, 41), np.linspace(-0.6, 0.6, 26), indexing="ij")
    tris, uvs = [], []
    for i in range(40):
        for j in range(25):
            a, b = (gx[i, j], gy[i, j]), (gx[i + 1, j], gy[i, j + 1])
            q = [(a[0], a[1]), (b[0], a[1]), (b[0], b[1]), (a[0], b[1])]
            uq = [((x + 1) / 2, (y + 0.6) / 1.2) for x, y in q]
            for t in ((0, 1, 2), (0, 2, 3)):
                tris.append([[q[k][0], q[k][1], 2.5] for k in t])
                uvs.append([uq[k] for k in t])
    tris, uvs = np.array(tris), np.array(uvs)
    emission = ImageParam((0.2 + rng.random((64, 128, 3)) * 3).astype(np.float32), 3, np.ones(3), "bench")
    mesh = MeshLight(tris, emission.bind(uvs.mean(axis=1)), True, uvs=uvs, emission=[emission],
                     slots=np.zeros(len(tris), np.int64))
    lights = {
        "point (delta)": PointLight(tr(0.5, 0.5, 2.0), 30.0, [1, 1, 1]),
        "spot + IES (delta)": SpotLight(tr(1.0, 1.0, 3.0), 60.0, [1, 1, 1], np.radians(70), 0.3,
                                        profile=IESEmission(IESProfile.from_file(ies))),
        "sphere": PointLight(tr(-0.5, -1.0, 1.5), 30.0, [1, 1, 1], radius=0.3),
        "soft-falloff disk": PointLight(tr(0.8, -0.9, 1.2), 25.0, [1, 1, 1], radius=0.2, soft_falloff=True),
        "area rectangle": AreaLight(tr(0.3, -0.2, 2.0), "rectangle", 1.2, 0.8, 40.0, [1, 1, 1]),
        "area + cutoff 35°": AreaLight(tr(0.3, -0.2, 2.0), "rectangle", 1.2, 0.8, 40.0, [1, 1, 1], True,
                                       SmoothCone(np.radians(35), np.radians(10))),
        "collimated": CollimatedAreaLight(tr(0, 0, 3.0), "square", 2.0, 2.0, 10.0, [1, 1, 1]),
        "sun 0.53°": SunLight(np.eye(4), 3.0, [1, 1, 1], np.radians(0.53)),
        "constant world": ConstantWorld([0.05, 0.06, 0.07]),
        "environment 512×1024": EnvironmentMap(rng.random((512, 1024, 3)) ** 3 * 4, 1.0),
        "mesh 2000 tris, textured": mesh,
    }
    for light in lights.values():
        light.prepare(np.zeros(3), 5.0)
    return lights


def many_lights(n=64):
    from backend.lights.area import AreaLight
    from backend.lights.point import PointLight
    rng = np.random.default_rng(3)
    out = []
    for k in range(n):
        m = np.eye(4)
        m[:3, 3] = rng.uniform(-4, 4, 3)
        out.append(AreaLight(m, "square", 0.5, 0.5, 20.0, [1, 1, 1]) if k % 2 else
                   PointLight(m, 20.0, [1, 1, 1], radius=0.1))
    return out


def per_lane(lanes: int, repeat: int) -> None:
    from backend.kernels.lights import batch
    from backend.kernels.lights.table import build_light_table
    from backend.kernels.params import ParamPacker

    lights = mixed_lights()
    packer = ParamPacker()
    lt = build_light_table(list(lights.values()), packer, 5.0, "local")
    tx = packer.table()
    rng = np.random.default_rng(0)
    p = np.column_stack([rng.uniform(-1.5, 1.5, lanes), rng.uniform(-1.5, 1.5, lanes), rng.uniform(-0.5, 1.4, lanes)])
    u = rng.random((lanes, 2))
    wi, dist, value, pdf, delta = np.empty((lanes, 3)), np.empty(lanes), np.empty((lanes, 3)), np.empty(lanes), np.empty(lanes, bool)

    def best(fn):
        fn()                                  # compile / load, warm the caches
        times = []
        for _ in range(repeat):
            t0 = time.process_time()      # CPU time: the machine may be shared
            fn()
            times.append(time.process_time() - t0)
        return min(times) / lanes * 1e9

    print(f"{lanes} lanes, best of {repeat}, ns per lane (one thread)")
    print("sample:")
    for li, name in enumerate(lights):
        ns = best(lambda: batch.sample(lt, tx, np.array([li], np.int64), p, u, wi, dist, value, pdf, delta))
        print(f"  {name:28s} {ns:7.1f}")
    out = np.empty(lanes)
    area = list(lights).index("area + cutoff 35°")
    batch.sample(lt, tx, np.array([area], np.int64), p, u, wi, dist, value, pdf, delta)
    t = np.where(pdf > 0, dist, 1.0)
    print(f"pdf_hit, area + cutoff 35°      {best(lambda: batch.pdf_hit(lt, np.array([area], np.int64), p, wi, t, out)):7.1f}")
    env = list(lights).index("environment 512×1024")
    print(f"pdf_escaped, environment        {best(lambda: batch.pdf_escaped(lt, np.array([env], np.int64), wi, out)):7.1f}")
    idx = np.empty(lanes, np.int64)
    print(f"select, local, {len(lights)} lights         {best(lambda: batch.select(lt, p, u[:, 0], idx, out)):7.1f}")
    lt64 = build_light_table(many_lights(), ParamPacker(), 5.0, "local")
    print(f"select, local, 64 lights         {best(lambda: batch.select(lt64, p, u[:, 0], idx, out)):7.1f}")
    print(f"select_prob, local, 64 lights    "
          f"{best(lambda: batch.select_prob(lt64, p, np.array([3], np.int64), out)):7.1f}")
    lt64p = build_light_table(many_lights(), ParamPacker(), 5.0, "power")
    print(f"select, power table, 64 lights   {best(lambda: batch.select(lt64p, p, u[:, 0], idx, out)):7.1f}")


def compile_all() -> float:
    """Compile (or load) every light batch entry point and the probe kernel; seconds."""
    t0 = time.perf_counter()
    from numba import njit

    from backend.kernels.lights import batch, dispatch
    from backend.kernels.lights.table import build_light_table
    from backend.kernels.params import ParamPacker

    lights = list(mixed_lights().values())
    packer = ParamPacker()
    lt = build_light_table(lights, packer, 5.0, "local")
    tx = packer.table()
    n = 4
    p = np.zeros((n, 3))
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    u = np.full((n, 2), 0.5)
    li = np.zeros(1, np.int64)
    f1, f3 = np.empty(n), np.empty((n, 3))
    batch.sample(lt, tx, li, p, u, f3.copy(), f1.copy(), f3.copy(), f1.copy(), np.empty(n, bool))
    batch.intersect(lt, li, p, d, np.full(n, np.inf), f1)
    batch.eval_hit(lt, li, p, d, f1, f3)
    batch.pdf_hit(lt, li, p, d, f1, f1)
    batch.eval_escaped(lt, li, d, f3)
    batch.pdf_escaped(lt, li, d, f1)
    batch.mesh_pdf_hit(lt, li, p, d, f1, np.zeros(n, np.int64), f1)
    batch.select(lt, p, u[:, 0], np.empty(n, np.int64), f1)
    batch.select_prob(lt, p, li, f1)

    @njit
    def probe(lt, tx, p, d, out):
        # every dispatch function once per lane: what an integrator kernel compiles
        for i in range(p.shape[0]):
            q = (p[i, 0], p[i, 1], p[i, 2])
            w = (d[i, 0], d[i, 1], d[i, 2])
            li, prob = dispatch.select(lt, q, 0.5)
            wi, dist, value, pdf, is_delta = dispatch.sample(lt, tx, max(li, 0), q, 0.3, 0.6)
            t = dispatch.intersect(lt, 0, q, w, np.inf)
            le = dispatch.eval_hit(lt, 0, q, w, t)
            e = dispatch.eval_escaped(lt, 0, w)
            lj, tri = dispatch.emitter_of_prim(lt, i)
            out[i] = (prob + value[0] + pdf + dispatch.pdf_hit(lt, 0, q, w, t) + le[0] + e[0]
                      + dispatch.pdf_escaped(lt, 0, w) + dispatch.select_prob(lt, q, 0)
                      + dispatch.mesh_pdf_hit(lt, max(lj, 0), q, w, 1.0, tri) + dist * 0.0 + (1.0 if is_delta else 0.0))

    probe(lt, tx, p, d, f1)
    return time.perf_counter() - t0


def cold_compile() -> None:
    import resource

    from backend.kernels import cache
    folder = cache.configure()
    print(f"kernel cache folder: {folder} (deleted)")
    shutil.rmtree(folder, ignore_errors=True)
    code = "import benchmarks.light_kernels as b; print(f'{b.compile_all():.1f}')"
    for label in ("cold (empty cache)", "warm (from the cache, new process)"):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                             env=dict(os.environ))
        total = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        print(f"{label}: {out.stdout.strip()} s compiling/loading (wall), whole process "
              f"{total:.1f} s wall, {cpu:.1f} s CPU")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--compile", action="store_true", help="measure the cold compile time instead")
    args = ap.parse_args(argv)
    if args.compile:
        cold_compile()
    else:
        per_lane(args.lanes, args.repeat)


if __name__ == "__main__":
    main()
