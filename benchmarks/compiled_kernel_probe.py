"""What compiled code would buy: a layered vertex function and a whole sample walk in Numba vs NumPy.

Context for issues 2 and 3, whose speed goals lie at or below what NumPy arithmetic costs
(benchmarks/numpy_floor.py, benchmarks/layered_floor.py). This probe answers the question
that decides between "compiled kernels" and "different goals": how much faster is one
vertex function — the rough dielectric connection of the layered BSDF (Walter et al. 2007,
Beckmann D, exact height-correlated Smith Λ, value plus the sampler's forward and reverse
densities, importance transport; backend/layered/kernels.py DielectricKernel.eval) — when it
runs as one compiled loop instead of ~100 NumPy array operations? Both versions get the same
direction pairs and must agree to 1e-9 relative (checked); the NumPy kernel is given its
masking terms precomputed (as the connection engine does), the compiled loop computes them.

Second, the whole forward walk of ``sample`` for the paper's Fig. 2 top stack (rough dielectric
n 1.5 α 0.05 / HG g 0.5, σt 1, albedo (0.5, 0.7, 0.95) / rough Cu α 0.05, Beckmann) as one
compiled loop per lane — interface sampling, free flights, phase sampling, the sample's Russian
roulette — against ``LayeredBSDF.sample`` on the same stack: the mean sample weight (the
directional albedo) must agree within 4 standard errors per channel, and the µs per sample are
compared with issue 3's goal (≤ 1.0 µs) and the NumPy walk.

Numba is *not* a dependency of Lamina: this script is a measurement for a design decision.

    .venv/bin/pip install numba      # into a scratch environment if you prefer
    .venv/bin/python -m benchmarks.compiled_kernel_probe [--repeat 5]
"""
from __future__ import annotations

import argparse
import math
import platform
import time

import numpy as np

from backend.layered.kernels import DielectricKernel, Microfacet3, rgb_rows
from backend.materials.microfacet import BECKMANN
from backend.materials.specfun import _NR

from .layered_throughput import directions

ETA, ALPHA = 1.5, 0.05   # the Fig. 2 top coat: dielectric n = 1.5, Beckmann α = 0.05


def compile_kernel():
    import numba

    nr = np.array(_NR)
    inv_sqrt_pi = 1.0 / math.sqrt(math.pi)

    @numba.njit(cache=False)
    def lam(x, y, z, au, av):
        # Exact Beckmann Smith Λ with Numerical Recipes' erfc (the same maths as kernels.lam).
        s = (au * au * x * x + av * av * y * y) / max(z * z, 1e-300)
        r = math.sqrt(max(s, 1e-200))
        if r <= 1.0 / 6.0:
            return 0.0
        a = 1.0 / r
        t = 1.0 / (1.0 + 0.5 * a)
        poly = nr[9]
        for i in range(8, -1, -1):
            poly = nr[i] + t * poly
        return max((0.5 * math.exp(-a * a)) * (r * inv_sqrt_pi - t * math.exp(poly)), 0.0)

    @numba.njit(cache=False)
    def fresnel(c, eta):
        eta_ti = eta if c >= 0 else 1.0 / eta
        ci = min(abs(c), 1.0)
        sin2_t = (1.0 - ci * ci) / (eta_ti * eta_ti)
        if sin2_t >= 1.0:
            return 1.0
        ct = math.sqrt(1.0 - sin2_t)
        a, b = eta_ti * ct, eta_ti * ci
        ds, dp = ci + a, b + ct
        if not (ds > 0 and dp > 0):
            return 1.0
        rs, rp = (ci - a) / ds, (b - ct) / dp
        return 0.5 * (rs * rs + rp * rp)

    @numba.njit(cache=False)
    def dielectric(wi, wo, eta, au, av, val, pf, pr):
        norm = 1.0 / (math.pi * au * av)
        for j in range(wi.shape[1]):
            val[j] = pf[j] = pr[j] = 0.0
            ci, co = wi[2, j], wo[2, j]
            refl = ci * co > 0
            e = eta if ci > 0 else 1.0 / eta          # n(wo side)/n(wi side) for transmission
            ew = 1.0 if refl else e
            hx, hy, hz = wi[0, j] + ew * wo[0, j], wi[1, j] + ew * wo[1, j], ci + ew * co
            l2 = hx * hx + hy * hy + hz * hz
            inv = (-1.0 if hz < 0 else 1.0) / math.sqrt(l2 if l2 > 0 else 1.0)
            hx, hy, hz = hx * inv, hy * inv, hz * inv
            if not hz > 0:
                continue
            cih = wi[0, j] * hx + wi[1, j] * hy + ci * hz
            coh = wo[0, j] * hx + wo[1, j] * hy + co * hz
            r_ok = refl and cih * coh > 0
            if not (r_ok or (ci * co < 0 and cih * coh < 0)):
                continue
            f = fresnel(cih, eta)
            fs = f if r_ok else 1.0 - f
            z2 = hz * hz
            d = math.exp(-(hx * hx / (au * au) + hy * hy / (av * av)) / z2) * norm / (z2 * z2)
            acih, acoh = abs(cih), abs(coh)
            den = cih + e * coh
            inv_d2 = 1.0 / (den * den)
            chi_i, chi_o = cih * ci > 0, coh * co > 0
            if chi_i and chi_o:
                g2 = 1.0 / (1.0 + lam(wi[0, j], wi[1, j], ci, au, av) + lam(wo[0, j], wo[1, j], co, au, av))
                jv = 0.25 if r_ok else acih * e * e * acoh * inv_d2
                val[j] = fs * d * g2 * jv / abs(ci)
            ph = d * hz                                 # the walk's D·cos θm sampler
            if chi_i:
                pf[j] = fs * ph * (0.25 / acoh if r_ok else e * e * acoh * inv_d2)
            if chi_o:
                pr[j] = fs * ph * (0.25 / acih if r_ok else acih * inv_d2)

    return dielectric, lam, numba.__version__


def compile_walk(lam):
    """The compiled forward walk of the Fig. 2 top stack (see the module docstring)."""
    import numba

    @numba.njit(cache=False)
    def beckmann_normal(au, av):
        # m ∝ D(m) cos θm (kernels.Microfacet3.sample, Beckmann branch)
        r = math.sqrt(-math.log1p(-min(np.random.random(), 1.0 - 2.0 ** -53)))
        phi = 2.0 * math.pi * np.random.random()
        x, y = -r * au * math.cos(phi), -r * av * math.sin(phi)
        inv = 1.0 / math.sqrt(1.0 + x * x + y * y)
        return x * inv, y * inv, inv

    @numba.njit(cache=False)
    def conductor_f(c, eta, k):
        c = min(abs(c), 1.0)
        c2 = c * c
        s2 = 1.0 - c2
        t0 = eta * eta - k * k - s2
        a2b2 = math.sqrt(t0 * t0 + 4.0 * eta * eta * k * k)
        a = math.sqrt(max(0.0, 0.5 * (a2b2 + t0)))
        t1, t2 = a2b2 + c2, 2.0 * a * c
        rs = (t1 - t2) / (t1 + t2) if t1 + t2 > 0 else 1.0
        t3, t4 = c2 * a2b2 + s2 * s2, t2 * s2
        rp = rs * ((t3 - t4) / (t3 + t4) if t3 + t4 > 0 else 1.0)
        return 0.5 * (min(max(rs, 0.0), 1.0) + min(max(rp, 0.0), 1.0))

    @numba.njit(cache=False)
    def walk(wi, eta_top, a_top, a_base, ceta, ck, g, tau, albedo, rr_start, rr_thresh, out_w, out_d):
        for j in range(wi.shape[1]):
            dx, dy, dz = -wi[0, j], -wi[1, j], -wi[2, j]     # travel direction
            layer, depth, on_iface = 0, 0.0, True
            b0 = b1 = b2 = 1.0
            out_w[0, j] = out_w[1, j] = out_w[2, j] = 0.0
            vertex = 0
            while True:
                vertex += 1
                ix, iy, iz = -dx, -dy, -dz                     # towards the previous vertex
                if on_iface and layer == 0:                    # rough dielectric, either side
                    mx, my, mz = beckmann_normal(a_top, a_top)
                    cim = ix * mx + iy * my + iz * mz
                    e = eta_top if cim >= 0 else 1.0 / eta_top
                    c = min(abs(cim), 1.0)
                    sin2_t = (1.0 - c * c) / (e * e)
                    tir = sin2_t >= 1.0
                    ct = math.sqrt(max(0.0, 1.0 - sin2_t))
                    a_, b_ = e * ct, e * c
                    ds, dp = c + a_, b_ + ct
                    f = 1.0
                    if not tir and ds > 0 and dp > 0:
                        rs, rp = (c - a_) / ds, (b_ - ct) / dp
                        f = 0.5 * (rs * rs + rp * rp)
                    cos_t = 0.0 if tir else (-ct if cim >= 0 else ct)
                    refl = np.random.random() < f
                    if refl:
                        ka, kb = 2.0 * cim, -1.0
                    else:
                        ka, kb = cim / e + cos_t, -1.0 / e
                    ox, oy, oz = ka * mx + kb * ix, ka * my + kb * iy, ka * mz + kb * iz
                    coh = cim if refl else cos_t
                    cc = oz * iz
                    side_ok = cc > 0 if refl else (cc < 0 and cos_t != 0.0)
                    if not (cim * iz > 0 and side_ok and coh * oz > 0):
                        break
                    g2 = 1.0 / (1.0 + lam(ix, iy, iz, a_top, a_top) + lam(ox, oy, oz, a_top, a_top))
                    w = g2 * abs(cim) / (abs(iz) * mz)
                    b0 *= w
                    b1 *= w
                    b2 *= w
                elif on_iface:                                 # rough conductor (the base)
                    s = -1.0 if iz < 0 else 1.0
                    ci = iz * s
                    mx, my, mz = beckmann_normal(a_base, a_base)
                    c = ix * mx + iy * my + ci * mz
                    ox, oy = 2.0 * c * mx - ix, 2.0 * c * my - iy
                    co = 2.0 * c * mz - ci
                    if not (ci > 0 and c > 0 and co > 0):
                        break
                    oz = co * s
                    w = (c / (ci * mz)) / (1.0 + lam(ix, iy, ci, a_base, a_base) + lam(ox, oy, co, a_base, a_base))
                    b0 *= conductor_f(c, ceta[0], ck[0]) * w
                    b1 *= conductor_f(c, ceta[1], ck[1]) * w
                    b2 *= conductor_f(c, ceta[2], ck[2]) * w
                else:                                          # HG phase sample about the travel direction
                    bb = 1.0 - 2.0 * np.random.random()
                    aa = 1.0 + g * bb
                    inv = 0.5 / (aa * aa)
                    omc = (1.0 - g) ** 2 * (1.0 - bb) * (1.0 + g + aa) * inv
                    opc = (1.0 + g) ** 2 * (1.0 + bb) * (1.0 - g + aa) * inv
                    cos_t = min(max(0.5 * (opc - omc), -1.0), 1.0)
                    sin_t = math.sqrt(max(omc * opc, 0.0))
                    phi = 2.0 * math.pi * np.random.random()
                    sign = 1.0 if dz >= 0 else -1.0
                    a2 = -1.0 / (sign + dz)
                    b2_ = dx * dy * a2
                    sc, ss = sin_t * math.cos(phi), sin_t * math.sin(phi)
                    ox = sc * (1.0 + sign * dx * dx * a2) + ss * b2_ + cos_t * dx
                    oy = sc * (sign * b2_) + ss * (sign + dy * dy * a2) + cos_t * dy
                    oz = -sc * (sign * dx) - ss * dy + cos_t * dz
                up = oz > 0
                if on_iface and ((up and layer == 0) or (not up and layer == 1)):
                    out_w[0, j], out_w[1, j], out_w[2, j] = b0, b1, b2
                    out_d[0, j], out_d[1, j], out_d[2, j] = ox, oy, oz
                    break
                bmax = max(b0, b1, b2)
                if abs(oz) < 1e-7 or bmax <= 0:
                    break
                if vertex >= rr_start:                         # walk.RR_SAMPLE
                    q = min(1.0, bmax / rr_thresh)
                    if not np.random.random() < q:
                        break
                    b0 /= q
                    b1 /= q
                    b2 /= q
                dx, dy, dz = ox, oy, oz
                # free flight through the slab (grey σt; the albedo weights a scattering event)
                s0 = depth if not on_iface else float(layer)
                dmax = max(s0 if dz > 0 else 1.0 - s0, 0.0)
                step = -math.log1p(-np.random.random()) * abs(dz) / tau
                if step < dmax:
                    depth = s0 - step if dz > 0 else s0 + step
                    on_iface = False
                    b0 *= albedo[0]
                    b1 *= albedo[1]
                    b2 *= albedo[2]
                else:
                    on_iface = True
                    layer = 0 if dz > 0 else 1

    @numba.njit(cache=False)
    def seed(value):
        np.random.seed(value)      # Numba's own generator: seeded inside compiled code

    seed(12345)
    return walk


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    try:
        t0 = time.perf_counter()
        compiled, lam, version = compile_kernel()
    except ImportError:
        print("numba is not installed (it is not a Lamina dependency): pip install numba, then run again")
        return 1
    ker = DielectricKernel(ETA, rgb_rows([1.0, 1.0, 1.0]), Microfacet3(BECKMANN, "", ALPHA, ALPHA),
                           np.asarray(False))
    rng = np.random.default_rng(3)
    print(f"machine: {platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}, "
          f"numba {version}; one process, CPU time, best of {args.repeat}")
    for m in (16384, 65536):
        wi = np.ascontiguousarray(directions(rng, m).T)
        wo = np.ascontiguousarray(directions(rng, m).T)
        wo[2] *= np.where(rng.random(m) < 0.5, -1.0, 1.0)     # half reflection, half transmission
        val, pf, pr = np.empty(m), np.empty(m), np.empty(m)
        compiled(wi, wo, ETA, ALPHA, ALPHA, val, pf, pr)       # compiles on the first call
        if m == 16384:
            print(f"compile time (first call): {time.perf_counter() - t0:.2f} s")
        ref = ker.eval(wi, wo, rng, True, False)
        worst = max(float(np.max(np.abs(x - r) / np.maximum(np.abs(r), 1e-300)))
                    for x, r in ((val, ref[0][0]), (pf, ref[1]), (pr, ref[2])))
        assert worst < 1e-9, f"the compiled kernel disagrees with kernels.py (relative {worst:.1e})"
        ti, to = ker.mask_terms(wi), ker.mask_terms(wo)
        best_np = best_nb = np.inf
        for _ in range(args.repeat):
            c0 = time.process_time()
            for _ in range(10):
                ker.eval(wi, wo, rng, True, False, ti=ti, to=to)
            best_np = min(best_np, (time.process_time() - c0) / 10 / m)
            c0 = time.process_time()
            for _ in range(10):
                compiled(wi, wo, ETA, ALPHA, ALPHA, val, pf, pr)
            best_nb = min(best_nb, (time.process_time() - c0) / 10 / m)
        print(f"{m:6d} pairs: NumPy {best_np * 1e9:5.0f} ns/pair (masking terms given), "
              f"compiled {best_nb * 1e9:5.0f} ns/pair (masking terms computed): {best_np / best_nb:4.1f}x; "
              f"largest relative difference {worst:.1e}")
    walk_probe(lam, args.repeat)
    return 0


def walk_probe(lam, repeat: int, lanes: int = 1 << 20, theta_deg: float = 30.0):
    from backend.materials.base import IMPORTANCE, ShadingContext

    from .layered_throughput import STACKS, load

    bsdf = load(STACKS["1 slab (Fig. 2 top)"]).bind(ShadingContext(np.zeros((lanes, 2))))
    st = bsdf.stack
    top, base, slab = st.kernels[0], st.kernels[1], st.slabs[0]
    assert not top.mf.separable and not base.mf.separable and not top.mf.ggx
    walk = compile_walk(lam)
    t = math.radians(theta_deg)
    wi = np.zeros((3, lanes))
    wi[0], wi[2] = math.sin(t), math.cos(t)
    args = (float(top.eta), float(top.mf.au), float(base.mf.au), np.ascontiguousarray(base.eta[:, 0]),
            np.ascontiguousarray(base.k[:, 0]), float(slab.phase.g), float(slab.tau[0, 0]),
            np.ascontiguousarray(slab.albedo[:, 0]), 4, 0.25)
    out_w, out_d = np.empty((3, lanes)), np.empty((3, lanes))
    walk(wi[:, :16], *args, out_w[:, :16], out_d[:, :16])          # compile
    best_nb = best_np = np.inf
    for _ in range(repeat):
        c0 = time.process_time()
        walk(wi, *args, out_w, out_d)
        best_nb = min(best_nb, (time.process_time() - c0) / lanes)
    rng = np.random.default_rng(11)
    wi_rows = np.ascontiguousarray(wi.T)
    for _ in range(max(1, repeat // 2)):
        c0 = time.process_time()
        smp = bsdf.sample(wi_rows, rng, IMPORTANCE, want_pdf=False)
        best_np = min(best_np, (time.process_time() - c0) / lanes)
    print(f"\nsample walk, 1 slab (Fig. 2 top), theta_i {theta_deg:.0f} deg, {lanes} lanes:")
    print(f"  compiled {best_nb * 1e6:5.2f} us per sample, NumPy {best_np * 1e6:5.2f} us per sample "
          f"({best_np / best_nb:4.1f}x); issue 3's goal <= 1.0 us")
    for ch, name in enumerate("RGB"):
        a, b = out_w[ch], smp.weight[:, ch]
        se = math.sqrt(a.var() / lanes + b.var() / lanes)
        z = (a.mean() - b.mean()) / se
        print(f"  albedo {name}: compiled {a.mean():.5f}, NumPy {b.mean():.5f} (z = {z:+.2f})")
        assert abs(z) < 4.0, "the compiled walk disagrees with LayeredBSDF.sample"


if __name__ == "__main__":
    raise SystemExit(main())
