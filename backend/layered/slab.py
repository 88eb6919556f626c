"""Free flights, transmittance and depth densities of one slab, structure-of-arrays.

The same maths as ``layered.medium.Medium`` (normalised depth 0 = top … 1 = bottom, rate per unit
depth along d = τ0·sigma_scale(d)/|d_z|; see its docstring), on (3, m) arrays for the walk's hot
loop; tests/test_layered_kernels.py checks both agree. Parameters come from the bound Medium:
``optical_depth`` and ``albedo`` ((1|n, 3)) and the phase function (``sigma_scale`` for
microflake media).

Chromatic extinction. ``Medium.free_flight`` weights each event with the channel-averaged density
(Mitsuba's balance strategy); along a walk those per-event weights multiply, and a channel with
a much smaller σt gains up to ×3 per grazing pass — heavy-tailed estimates (measured: single
samples 200× the mean). The walk instead uses path-level spectral MIS (the balance heuristic
over the three channels for the *whole* path, as pbrt-v4's volumetric integrator does with hero
wavelengths): a hero channel is drawn once per walk, every free flight samples with the hero's
rate, and the walk keeps per-channel density ratios r_c = p_c(path)/p_hero(path). The throughput
stored is f_c(path)/mean_c p_c(path), bounded by 3·f_c/p_c; ``spectral_step`` keeps r normalised
to mean 1 so that this is the plain throughput.
"""
from __future__ import annotations

import numpy as np

from .kernels import rgb_rows

GRAZING = 1e-7


class SlabOps:
    def __init__(self, medium, tau=None, albedo=None):
        self.medium = medium
        self.phase = medium.phase
        self.directional = bool(medium.phase.directional)
        self.grey = bool(medium.grey)
        self.tau = rgb_rows(medium.optical_depth) if tau is None else tau   # (3, 1|n)
        self.albedo = rgb_rows(medium.albedo) if albedo is None else albedo  # (3, 1|n)

    @property
    def constant(self) -> bool:
        """No per-lane parameter (``take`` returns the operator itself)."""
        return self.tau.shape[1] == 1 and self.albedo.shape[1] == 1 and self.phase.n is None

    def take(self, idx) -> "SlabOps":
        if self.constant:
            return self
        med = self.medium.take(idx)
        return SlabOps(med, self.tau if self.tau.shape[1] == 1 else self.tau[:, idx],
                       self.albedo if self.albedo.shape[1] == 1 else self.albedo[:, idx])

    def rate(self, d):
        """Extinction per unit depth along d: (m,) if grey else (3, m); and the alive mask."""
        az = np.abs(d[2])
        alive = az >= GRAZING
        inv = 1.0 / np.where(alive, az, 1.0)
        if self.directional:
            inv = inv * self.phase.sigma_scale(d.T)
        if self.grey:
            return self.tau[0] * inv, alive
        return self.tau * inv, alive

    def transmittance(self, d, s0, s1):
        """(3, m) (or (m,) if grey) transmittance from normalised depth s0 to s1 along d, 0 if d
        does not lead there; 1 over zero length."""
        r, alive = self.rate(d)
        diff = s1 - s0
        reach = ((diff * -d[2] > 0) & alive) | (diff == 0)
        return np.where(reach, np.exp(-r * np.abs(diff)), 0.0)

    def depth_pdf(self, d, s0, s1, to_medium, channel=None):
        """(m,) density of producing depth s1 from s0 along d by a free flight: per unit depth if
        ``to_medium`` (a scattering vertex), else the probability of reaching the boundary.
        Chromatic media: the channel mean, or channel ``channel`` (m,) alone if given (a hero
        channel's single-channel sampler, as stochastic-pdf walks use)."""
        r, alive = self.rate(d)
        if channel is not None and not self.grey:
            r = np.take_along_axis(r, np.asarray(channel)[None, :], axis=0)[0]
        e = np.exp(-r * np.abs(s1 - s0))
        t = np.where(to_medium, r * e, e)
        if t.ndim == 2:
            t = t.mean(axis=0)
        return np.where(alive, t, 0.0)

    def spectral_step(self, s0, d, rng, hero, r):
        """A chromatic free flight with hero channel ``hero`` (m,) and density ratios ``r``
        (3, m, mean 1). Returns (new depth, scattered, throughput factor (3, m), new r,
        channel-mean density (m,) for the bidirectional MIS, alive)."""
        m = d.shape[1]
        rate, alive = self.rate(d)
        up = d[2] > 0
        dmax = np.maximum(np.where(up, s0, 1.0 - s0), 0.0)
        rh = np.take_along_axis(rate, hero[None, :], axis=0)[0]
        with np.errstate(divide="ignore"):
            step = -np.log1p(-rng.random(m)) / rh
        scattered = (step < dmax) & alive
        step = np.where(scattered, step, dmax)
        new_s = np.where(scattered, np.where(up, s0 - step, s0 + step), np.where(up, 0.0, 1.0))
        e = np.exp(-rate * step)
        p_c = np.where(scattered, rate * e, e)                   # per-channel event densities
        f_c = np.where(scattered, self.albedo * rate * e, e)     # per-channel event values
        r_new = r * p_c                                          # ∝ p_c(path), common scale dropped
        mean_r = r_new.mean(axis=0)
        ok = alive & (mean_r > 0)
        inv = 1.0 / np.where(ok, mean_r, 1.0)
        # throughput_c ← throughput_c · f_c · mean(r_old) / mean(r_new), with mean(r_old) = 1
        factor = np.where(ok, f_c * inv, 0.0)
        r_new = np.where(ok, r_new * inv, 1.0)
        return new_s, scattered, factor, r_new, np.where(alive, p_c.mean(axis=0), 0.0), alive

    def spectral_flight(self, s0, d, rng, hero, r, rate, alive, dmax, prev_medium=None):
        """``spectral_step`` for the walk, with the rate (3, m), alive mask and depth to the
        boundary precomputed. Returns (step, scattered, throughput factor (3, m), new r,
        channel-mean density of the event (m,), channel-mean reverse density of the previous
        vertex's depth (m,) if ``prev_medium`` is given, else None)."""
        m = d.shape[1]
        rh = np.take_along_axis(rate, hero[None, :], axis=0)[0]
        with np.errstate(divide="ignore"):
            step = -np.log1p(-rng.random(m)) / rh
        scattered = (step < dmax) & alive
        step = np.where(scattered, step, dmax)
        e = np.exp(-rate * step)
        re = rate * e
        p_c = np.where(scattered, re, e)                         # per-channel event densities
        f_c = np.where(scattered, self.albedo * re, e)           # per-channel event values
        r_new = r * p_c                                          # ∝ p_c(path), common scale dropped
        mean_r = r_new.mean(axis=0)
        ok = alive & (mean_r > 0)
        inv = 1.0 / np.where(ok, mean_r, 1.0)
        # throughput_c ← throughput_c · f_c · mean(r_old) / mean(r_new), with mean(r_old) = 1
        factor = np.where(ok, f_c * inv, 0.0)
        r_new = np.where(ok, r_new * inv, 1.0)
        dens = np.where(alive, p_c.mean(axis=0), 0.0)
        drev = None
        if prev_medium is not None:
            drev = np.where(alive, np.where(prev_medium, re, e).mean(axis=0), 0.0)
        return step, scattered, factor, r_new, dens, drev

    def free_flight(self, s0, d, rng):
        """(new depth, scattered, weight (3, m) or broadcastable, pdf (m,), alive)."""
        m = d.shape[1]
        r, alive = self.rate(d)
        up = d[2] > 0
        dmax = np.maximum(np.where(up, s0, 1.0 - s0), 0.0)
        if self.grey:
            u = rng.random(m)
            rc = r
        else:
            u2 = rng.random((2, m))
            u = u2[0]
            ch = np.minimum((u2[1] * 3.0).astype(np.int64), 2)
            rc = np.take_along_axis(r, ch[None, :], axis=0)[0]
        with np.errstate(divide="ignore"):
            step = -np.log1p(-u) / rc
        scattered = (step < dmax) & alive
        step = np.where(scattered, step, dmax)
        new_s = np.where(scattered, np.where(up, s0 - step, s0 + step), np.where(up, 0.0, 1.0))
        if self.grey:
            e = np.exp(-r * step)
            pdf = np.where(scattered, r * e, e)
            weight = np.where(scattered, self.albedo, 1.0)
        else:
            with np.errstate(divide="ignore"):
                log_rate = np.where(scattered, np.log(r), 0.0)
            log_term = log_rate - r * step
            top = np.max(log_term, axis=0)
            top = np.where(np.isfinite(top), top, 0.0)
            rel = np.exp(log_term - top)
            mean_rel = rel.mean(axis=0)
            ok = mean_rel > 0
            weight = np.where(scattered, self.albedo, 1.0) * rel / np.where(ok, mean_rel, 1.0)
            weight = np.where(ok, weight, 0.0)
            pdf = mean_rel * np.exp(top)
        weight = np.where(alive, weight, 0.0)
        return new_s, scattered, weight, np.where(alive, pdf, 0.0), alive
