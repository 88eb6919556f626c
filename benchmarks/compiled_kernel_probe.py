"""What a compiled kernel would buy: the layered walk's heaviest vertex function in Numba vs NumPy.

Context for issues 2 and 3, whose speed goals lie at or below what NumPy arithmetic costs
(benchmarks/numpy_floor.py, benchmarks/layered_floor.py). This probe answers the question
that decides between "compiled kernels" and "different goals": how much faster is one
vertex function — the rough dielectric connection of the layered BSDF (Walter et al. 2007,
Beckmann D, exact height-correlated Smith Λ, value plus the sampler's forward and reverse
densities, importance transport; backend/layered/kernels.py DielectricKernel.eval) — when it
runs as one compiled loop instead of ~100 NumPy array operations? Both versions get the same
direction pairs and must agree to 1e-9 relative (checked); the NumPy kernel is given its
masking terms precomputed (as the connection engine does), the compiled loop computes them.

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

    return dielectric, numba.__version__


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    try:
        t0 = time.perf_counter()
        compiled, version = compile_kernel()
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
