"""Helpers for the light tests: Monte Carlo irradiance with standard errors, direction
chi-square tests against a light's MIS density, and small geometry written independently of the
code under test."""
import numpy as np
from scipy import stats

K_SIGMA = 4.0


def frame(n):
    """Orthonormal (s, t, n) rows for unit vector n (3,), independent of backend.mathutil."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    s = np.cross(n, a)
    s /= np.linalg.norm(s)
    t = np.cross(n, s)
    return s, t, n


def nee_irradiance(light, p, normal, n_samples, rng):
    """Mean and standard error of value · max(cos, 0) from ``light.sample`` at one point."""
    pts = np.broadcast_to(np.asarray(p, float), (n_samples, 3)).copy()
    s = light.sample(pts, rng.random((n_samples, 2)))
    e = s.value * np.maximum(s.wi @ np.asarray(normal, float), 0.0)[:, None]
    return e.mean(axis=0), e.std(axis=0, ddof=1) / np.sqrt(n_samples), s


def cosine_directions(normal, n, rng):
    """Cosine-distributed directions about ``normal`` (pdf cos/π), written for the tests."""
    u = rng.random((n, 2))
    r = np.sqrt(u[:, 0])
    phi = 2 * np.pi * u[:, 1]
    z = np.sqrt(np.maximum(0.0, 1 - u[:, 0]))
    s, t, nn = frame(normal)
    return (r * np.cos(phi))[:, None] * s + (r * np.sin(phi))[:, None] * t + z[:, None] * nn


def bsdf_irradiance(light, p, normal, n_samples, rng):
    """Irradiance from cosine-sampled rays that hit the light (intersect + eval_hit): π L."""
    d = cosine_directions(normal, n_samples, rng)
    o = np.broadcast_to(np.asarray(p, float), d.shape).copy()
    t = light.intersect(o, d, np.full(n_samples, np.inf))
    hit = np.isfinite(t)
    e = np.zeros((n_samples, 3))
    e[hit] = np.pi * light.eval_hit(o[hit], d[hit], t[hit])
    return e.mean(axis=0), e.std(axis=0, ddof=1) / np.sqrt(n_samples)


def pdf_of_directions(light, o, d):
    """The density ``light.sample(o)`` claims for directions d (0 where the light is not hit)."""
    if getattr(light, "is_infinite", False):
        return light.pdf_escaped(d)
    oo = np.broadcast_to(o, d.shape).copy()
    t = light.intersect(oo, d, np.full(d.shape[0], np.inf))
    hit = np.isfinite(t)
    pdf = np.zeros(d.shape[0])
    pdf[hit] = light.pdf_hit(oo[hit], d[hit], t[hit])
    return pdf


def chi2_directions(light, o, axis, cos_min, n_samples, rng, n_theta=16, n_phi=24, sub=12,
                    pdf=None):
    """Chi-square test of the directions ``light.sample(o)`` produces (successful samples only)
    against the density ``pdf(d)`` (default: intersect + pdf_hit / pdf_escaped).

    Bins: n_theta × n_phi cells uniform in cos θ ∈ [cos_min, 1] and φ around ``axis`` plus one
    bin for failed samples; expected cell probabilities by a sub × sub midpoint rule in
    (cos θ, φ), where dω = d cos θ dφ. Returns (p-value, samples outside the cells, total mass).
    """
    pdf = pdf or (lambda d: pdf_of_directions(light, o, d))
    s, t, n = frame(axis)
    o = np.asarray(o, float)
    # expected
    dc = (1.0 - cos_min) / (n_theta * sub)
    dp = 2 * np.pi / (n_phi * sub)
    c = cos_min + (np.arange(n_theta * sub) + 0.5) * dc
    ph = (np.arange(n_phi * sub) + 0.5) * dp
    C, PH = np.meshgrid(c, ph, indexing="ij")
    sn = np.sqrt(np.maximum(0.0, 1 - C * C))
    dirs = (sn * np.cos(PH))[..., None] * s + (sn * np.sin(PH))[..., None] * t + C[..., None] * n
    dens = pdf(dirs.reshape(-1, 3)).reshape(C.shape) * dc * dp
    expected = dens.reshape(n_theta, sub, n_phi, sub).sum(axis=(1, 3)).ravel()
    mass = expected.sum()
    # observed
    pts = np.broadcast_to(o, (n_samples, 3)).copy()
    smp = light.sample(pts, rng.random((n_samples, 2)))
    ok = smp.pdf > 0          # every produced direction, also those carrying no light
    w = smp.wi[ok]
    cw = np.clip(w @ n, -1, 1)
    pw = np.mod(np.arctan2(w @ t, w @ s), 2 * np.pi)
    outside = int(np.sum(cw < cos_min - 1e-12))
    it = np.clip(((cw - cos_min) / (1 - cos_min) * n_theta).astype(int), 0, n_theta - 1)
    ip = np.clip((pw / (2 * np.pi) * n_phi).astype(int), 0, n_phi - 1)
    observed = np.bincount(it * n_phi + ip, minlength=n_theta * n_phi).astype(float)
    p_value = chi2_pvalue(np.append(observed, n_samples - ok.sum()),
                          np.append(expected, max(1.0 - mass, 0.0)) * n_samples)
    return p_value, outside, mass


def chi2_on_plane(light, o, center, eu, ev, urange, vrange, n_samples, rng, n_bins=16, sub=24):
    """Chi-square test of the points ``light.sample(o)`` produces on a planar emitter, binned in
    the emitter's own coordinates (eu, ev unit axes from ``center``) over urange × vrange, against
    the density that ``pdf_hit`` claims, converted to area measure (pdf_ω · |cos θ_l| / t²) and
    integrated by a sub × sub midpoint rule per bin. Returns (p-value, samples outside the
    binned range, total expected mass)."""
    o = np.asarray(o, float)
    center = np.asarray(center, float)
    eu, ev = np.asarray(eu, float), np.asarray(ev, float)
    normal = np.cross(eu, ev)
    (u0, u1), (v0, v1) = urange, vrange
    k = n_bins * sub
    us = u0 + (np.arange(k) + 0.5) * ((u1 - u0) / k)
    vs = v0 + (np.arange(k) + 0.5) * ((v1 - v0) / k)
    U, V = np.meshgrid(us, vs, indexing="ij")
    x = center + U[..., None] * eu + V[..., None] * ev
    d = (x - o).reshape(-1, 3)
    t = np.linalg.norm(d, axis=1)
    w = d / t[:, None]
    dens = pdf_of_directions(light, o, w) * np.abs(w @ normal) / (t * t)
    cell = (u1 - u0) / k * (v1 - v0) / k
    expected = (dens.reshape(n_bins, sub, n_bins, sub).sum(axis=(1, 3)) * cell).ravel()
    mass = expected.sum()
    pts = np.broadcast_to(o, (n_samples, 3)).copy()
    smp = light.sample(pts, rng.random((n_samples, 2)))
    ok = smp.pdf > 0
    hit = o + smp.wi[ok] * smp.dist[ok, None] - center
    hu, hv = hit @ eu, hit @ ev
    tol = 1e-9 * max(u1 - u0, v1 - v0)
    outside = int(np.sum((hu < u0 - tol) | (hu > u1 + tol) | (hv < v0 - tol) | (hv > v1 + tol)))
    iu = np.clip(((hu - u0) / (u1 - u0) * n_bins).astype(int), 0, n_bins - 1)
    iv = np.clip(((hv - v0) / (v1 - v0) * n_bins).astype(int), 0, n_bins - 1)
    observed = np.bincount(iu * n_bins + iv, minlength=n_bins * n_bins).astype(float)
    p_value = chi2_pvalue(np.append(observed, n_samples - ok.sum()),
                          np.append(expected, max(1.0 - mass, 0.0)) * n_samples)
    return p_value, outside, mass


def chi2_pvalue(observed, expected, min_expected=5.0):
    """Pearson chi-square p-value, pooling cells with expected count < min_expected."""
    observed = np.asarray(observed, float)
    expected = np.asarray(expected, float)
    small = expected < min_expected
    obs = list(observed[~small])
    exp = list(expected[~small])
    if small.any():
        pooled_e = expected[small].sum()
        pooled_o = observed[small].sum()
        if pooled_e >= min_expected:
            obs.append(pooled_o)
            exp.append(pooled_e)
        else:
            # Too little expected mass to test: it must not hold a noticeable number of samples.
            assert pooled_o <= max(10.0, 10 * pooled_e), (pooled_o, pooled_e)
    obs, exp = np.array(obs), np.array(exp)
    stat = float(np.sum((obs - exp) ** 2 / exp))
    return float(stats.chi2.sf(stat, len(obs) - 1))


def check_mis_consistency(light, o, n, rng):
    """Samples with value > 0: pdf == pdf_hit at the sampled direction, value == eval_hit/pdf."""
    pts = np.broadcast_to(np.asarray(o, float), (n, 3)).copy()
    s = light.sample(pts, rng.random((n, 2)))
    ok = np.any(s.value > 0, axis=1)
    assert ok.any()
    t = light.intersect(pts[ok], s.wi[ok], np.full(int(ok.sum()), np.inf))
    assert np.all(np.isfinite(t))
    assert np.allclose(t, s.dist[ok], rtol=1e-7)
    ph = light.pdf_hit(pts[ok], s.wi[ok], t)
    assert np.allclose(ph, s.pdf[ok], rtol=1e-9)
    le = light.eval_hit(pts[ok], s.wi[ok], t)
    assert np.allclose(le / ph[:, None], s.value[ok], rtol=1e-9)
    return ok.mean()


def rect_irradiance_parallel(x0, x1, y0, y1, h, radiance):
    """Irradiance at a point facing a parallel rectangle [x0,x1]×[y0,y1] at height h (point at the
    origin of those coordinates), from the corner form factor (Howell's catalogue, B-3)."""
    def corner(a, b):
        A, B = a / h, b / h
        return (A / np.sqrt(1 + A * A) * np.arctan(B / np.sqrt(1 + A * A))
                + B / np.sqrt(1 + B * B) * np.arctan(A / np.sqrt(1 + B * B))) / (2 * np.pi)

    f = 0.0
    for x, sx in ((x1, 1), (x0, -1)):
        for y, sy in ((y1, 1), (y0, -1)):
            f += sx * sy * np.sign(x) * np.sign(y) * corner(abs(x), abs(y))
    return np.pi * radiance * f


def polygon_irradiance(p, normal, verts, radiance):
    """Lambert's formula for a uniformly emitting polygon fully above the receiver's horizon:
    E = L/2 Σ_i Θ_i (n · Γ_i), Θ_i the angle edge i subtends, Γ_i the unit normal of its plane."""
    q = [np.asarray(v, float) - p for v in verts]
    q = [v / np.linalg.norm(v) for v in q]
    e = 0.0
    for i in range(len(q)):
        a, b = q[i], q[(i + 1) % len(q)]
        g = np.cross(a, b)
        theta = np.arctan2(np.linalg.norm(g), np.dot(a, b))
        e += theta * np.dot(normal, g / np.linalg.norm(g))
    return 0.5 * radiance * abs(e)


def translate(x, y, z, linear=None):
    m = np.eye(4)
    if linear is not None:
        m[:3, :3] = linear
    m[:3, 3] = (x, y, z)
    return m


def rot_x(deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], float)


def rot_z(deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], float)
