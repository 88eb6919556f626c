"""The least shading work a NumPy wavefront path tracer can do, against embree's ray casting.

Context for issue 2's target "shading overhead ≤ 1× the ray-casting time" (benchmarks/
core_throughput.py measures the real renderer). This script renders the same Cornell-like box
with a deliberately minimal tracer: every surface Lambertian (the material's colour, glass and
gold included), one square light sampled by area (no spherical-rectangle sampling, no MIS, no light
selection), next-event estimation with one shadow ray per bounce, cosine-weighted continuation,
Russian roulette, compaction, no AOVs, no textures, no emission hits. It is *not* a correct
renderer of that scene; it is a lower bound on the array work per bounce that any NumPy integrator
with NEE does, so its overhead ratio says how far the ≤ 1× target is from what NumPy can reach at
all. Shading state in float32 (the floor) or float64 (what the renderer uses, materials/base.py).

    .venv/bin/python -m benchmarks.numpy_floor [--size 256] [--spp 16] [--dtype float32]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from backend.geometry.accel import Accelerator, retrace
from backend.materials.base import ShadingContext
from backend.scene.loader import load_scene_data

from .scenes import cornell_box

LIGHT_Z = 1.98          # m, the square light of scenes.cornell_box (0.5 m side, facing −Z)
LIGHT_HALF = 0.25       # m
LIGHT_RADIANCE = np.array([60.0 / (0.25 * np.pi), 60.0 * 0.85 / (0.25 * np.pi), 60.0 * 0.7 / (0.25 * np.pi)])
# W/(m²·sr): Cycles' area light power P over area A and π (Lambertian emitter), colour (1, .85, .7)


def render_floor(scene, accel, spp: int, dtype, rng, max_bounces: int) -> np.ndarray:
    soup = scene.soup
    W, H = scene.width, scene.height
    v0 = soup.vertices[:, 0].astype(np.float64).astype(dtype)
    e1 = (soup.vertices[:, 1].astype(np.float64) - soup.vertices[:, 0]).astype(dtype)
    e2 = (soup.vertices[:, 2].astype(np.float64) - soup.vertices[:, 0]).astype(dtype)
    ng = soup.geo_normal.astype(dtype)
    # Lambertian stand-in for every material: its albedo AOV colour (materials/base.py).
    ctx = ShadingContext(np.full((1, 2), 0.5))
    colour = np.array([np.broadcast_to(m.bind(ctx).albedo(), (1, 3))[0] for m in scene.materials], dtype)
    albedo_of_tri = colour[soup.material]
    n = W * H * spp
    pix = np.repeat(np.arange(W * H), spp)
    st = np.stack([(pix % W + rng.random(n, dtype)) / W, (pix // W + rng.random(n, dtype)) / H], axis=1)
    o, d, tmin, _ = scene.camera.generate_rays(st.astype(np.float64), None)
    o, d = o.astype(dtype), d.astype(dtype)
    L = np.zeros((n, 3), dtype)
    beta = np.ones((n, 3), dtype)
    lane = np.arange(n)
    Le = LIGHT_RADIANCE.astype(dtype)
    area = dtype(4 * LIGHT_HALF * LIGHT_HALF)
    for bounce in range(max_bounces + 1):
        prim, t, b1, b2 = accel.intersect(o, d, None)
        hit = prim >= 0
        lane, beta, prim, b1, b2, d = lane[hit], beta[hit], prim[hit], b1[hit].astype(dtype), b2[hit].astype(dtype), d[hit]
        if not lane.size:
            break
        p = v0[prim] + b1[:, None] * e1[prim] + b2[:, None] * e2[prim]
        nrm = ng[prim]
        nrm *= np.where(np.einsum("ij,ij->i", nrm, d) > 0, -1, 1).astype(dtype)[:, None]
        rho = albedo_of_tri[prim]
        # NEE: a point on the light by area; solid-angle conversion cos_l / dist².
        u = rng.random((lane.size, 2), dtype)
        q = np.empty_like(p)
        q[:, 0] = (u[:, 0] - 0.5) * (2 * LIGHT_HALF)
        q[:, 1] = (u[:, 1] - 0.5) * (2 * LIGHT_HALF)
        q[:, 2] = LIGHT_Z
        to = q - p
        dist2 = np.einsum("ij,ij->i", to, to)
        dist = np.sqrt(dist2)
        wl = to / dist[:, None]
        cos_s = np.einsum("ij,ij->i", wl, nrm)
        cos_l = wl[:, 2]                       # the light faces −Z: cos at the light = w_z
        g = np.maximum(cos_s, 0) * np.maximum(cos_l, 0) * area / np.maximum(dist2, 1e-12) / np.pi
        contrib = beta * rho * (g[:, None] * Le)
        org = p + nrm * dtype(1e-4)
        blocked = accel.occluded(org, wl, dist * dtype(0.999))
        L[lane[~blocked]] += contrib[~blocked]
        if bounce == max_bounces:
            break
        # Cosine-weighted continuation: weight = albedo.
        u = rng.random((lane.size, 2), dtype)
        r = np.sqrt(u[:, 0])
        phi = dtype(2 * np.pi) * u[:, 1]
        x, y, z = r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u[:, 0])
        # Orthonormal basis from the normal (branchless, Duff et al. 2017).
        sgn = np.where(nrm[:, 2] >= 0, 1, -1).astype(dtype)
        a = -1 / (sgn + nrm[:, 2])
        bb = nrm[:, 0] * nrm[:, 1] * a
        s = np.stack([1 + sgn * nrm[:, 0] ** 2 * a, sgn * bb, -sgn * nrm[:, 0]], axis=1)
        tt = np.stack([bb, sgn + nrm[:, 1] ** 2 * a, -nrm[:, 1]], axis=1)
        d = s * x[:, None] + tt * y[:, None] + nrm * z[:, None]
        beta = beta * rho
        if bounce >= 2:
            q_rr = np.minimum(beta.max(axis=1), 1)
            live = rng.random(lane.size, dtype) < q_rr
            beta = beta[live] / q_rr[live, None]
            lane, org, d = lane[live], org[live], d[live]
        o = org
    return L


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--max-bounces", type=int, default=6)
    ap.add_argument("--dtype", choices=("float32", "float64"), default="float32")
    ap.add_argument("--repeat", type=int, default=3, help="best of N (CPU time; robust to a busy machine)")
    args = ap.parse_args(argv)
    scene = load_scene_data(cornell_box(args.size, args.size, args.spp, args.max_bounces), "<cornell>")
    accel = Accelerator(scene.soup)
    accel.intersect(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), None)   # warm-up
    dtype = np.dtype(args.dtype).type
    total = embree = np.inf
    for _ in range(args.repeat):
        rng = np.random.default_rng(1)
        accel.recorder = []
        accel.rays_traced = 0
        t0 = time.process_time()
        L = render_floor(scene, accel, args.spp, dtype, rng, args.max_bounces)
        total = min(total, time.process_time() - t0)
        # embree alone on the same rays, as benchmarks/core_throughput.py measures it
        batches, accel.recorder = accel.recorder, None
        c0 = time.process_time()
        retrace(accel, batches)
        embree = min(embree, time.process_time() - c0)
    shading = total - embree
    print(f"minimal NumPy tracer ({args.dtype} state), Cornell-like box {args.size}², {args.spp} spp, "
          f"{accel.rays_traced} rays, mean pixel value {L.mean():.4f}")
    print(f"best CPU time of {args.repeat}: total {total:.3f} s, embree {embree:.3f} s, shading {shading:.3f} s")
    print(f"shading overhead of the floor: {shading / embree:.2f}x the ray-casting time")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
