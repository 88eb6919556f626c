"""Statistics helpers for direction samplers: binned quadrature of a pdf and a chi-square test.

Bins are (θ, φ) cells about an arbitrary axis; a pdf is integrated over each cell with tensor
Gauss–Legendre nodes (independent of the sampler under test), samples are histogrammed in the
same cells, cells with expected counts < 5 are pooled, and Pearson's statistic gives a p-value.
"""
from __future__ import annotations

import numpy as np
from scipy import stats


def frame(axis):
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(helper, a)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    return e1, e2, a


def cone_edges(theta_c=None, widths=(), n_uniform=60, fine=24):
    """θ edges in [0, π]: uniform, refined around θ = 0 (geometric) and around theta_c."""
    edges = [np.linspace(0.0, np.pi, n_uniform + 1)]
    for w in widths:
        if theta_c is None:
            edges.append(np.geomspace(w, 0.5, fine))
        else:
            edges.append(np.clip(theta_c + np.linspace(-6 * w, 6 * w, fine), 0.0, np.pi))
    e = np.unique(np.round(np.concatenate(edges), 14))
    return e


def bin_integrals(pdf_fn, axis, theta_edges, n_phi, nodes=8):
    """∫ pdf over each (θ, φ) cell; returns (len(theta_edges) − 1, n_phi)."""
    e1, e2, a = frame(axis)
    x, w = np.polynomial.legendre.leggauss(nodes)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    t0, t1 = theta_edges[:-1], theta_edges[1:]
    phi_edges = np.linspace(0.0, 2.0 * np.pi, n_phi + 1)
    p0, p1 = phi_edges[:-1], phi_edges[1:]
    th = t0[:, None] + (t1 - t0)[:, None] * x[None, :]            # (T, q)
    ph = p0[:, None] + (p1 - p0)[:, None] * x[None, :]            # (P, q)
    wt = (t1 - t0)[:, None] * w[None, :] * np.sin(th)
    wp = (p1 - p0)[:, None] * w[None, :]
    st, ct = np.sin(th), np.cos(th)
    # directions (T, q, P, q, 3)
    d = (st[:, :, None, None, None] * (np.cos(ph)[None, None, :, :, None] * e1 + np.sin(ph)[None, None, :, :, None] * e2)
         + ct[:, :, None, None, None] * a)
    shape = d.shape[:4]
    vals = pdf_fn(d.reshape(-1, 3)).reshape(shape)
    return np.einsum("tiqj,ti,qj->tq", vals, wt, wp)


def histogram(dirs, axis, theta_edges, n_phi):
    e1, e2, a = frame(axis)
    ct = np.clip(dirs @ a, -1.0, 1.0)
    th = np.arctan2(np.linalg.norm(np.cross(dirs, a), axis=1), ct)
    ph = np.mod(np.arctan2(dirs @ e2, dirs @ e1), 2.0 * np.pi)
    ti = np.clip(np.searchsorted(theta_edges, th, side="right") - 1, 0, len(theta_edges) - 2)
    pj = np.clip((ph / (2.0 * np.pi) * n_phi).astype(int), 0, n_phi - 1)
    h = np.zeros((len(theta_edges) - 1, n_phi))
    np.add.at(h, (ti, pj), 1.0)
    return h


def chi2_pvalue(observed, expected, min_expected=5.0):
    o, e = observed.ravel(), expected.ravel()
    small = e < min_expected
    o2 = np.append(o[~small], o[small].sum())
    e2 = np.append(e[~small], e[small].sum())
    keep = e2 > 0
    if np.any(o2[~keep] > 0):
        return 0.0  # samples where the pdf says there are none
    o2, e2 = o2[keep], e2[keep]
    stat = float(((o2 - e2) ** 2 / e2).sum())
    return float(stats.chi2.sf(stat, len(o2) - 1))
