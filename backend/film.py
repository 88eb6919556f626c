"""Pixel filters (importance sampled, as Cycles) and the film accumulator.

Filter importance sampling: each camera sample's offset from the pixel centre is drawn from the
filter's (separable) 1-D profile, so every sample has weight 1 and the pixel value is a plain mean.
This is what Cycles does (its default: Blackman–Harris, width 1.5 px). Consequence worth knowing:
the filter must be non-negative (no Mitchell/Lanczos lobes).
"""
from __future__ import annotations

import numpy as np

from .passes import NO_LANES
from .scene.reader import Node


#: Filter support in units of the width, as Cycles' ``filter_table`` (scene/film.cpp) stretches
#: it: Blackman-Harris spans ±width (2 × width), the Gaussian ±1.5 width, the box ±width/2. So a
#: Blender filter width renders the same in Lamina and Cycles (measured by the peer benchmark:
#: with the full support equal to the width, edges differed from Cycles by up to 13 σ).
SUPPORT = {"box": 1.0, "blackman-harris": 2.0, "gaussian": 3.0}


class PixelFilter:
    TABLE = 1024

    def __init__(self, kind: str = "blackman-harris", width: float = 1.5):
        self.kind = kind
        self.width = width                          # Blender's / Cycles' filter width [pixels]
        self.support = SUPPORT[kind] * width        # the full span of the offsets [pixels]
        x = (np.arange(self.TABLE) + 0.5) / self.TABLE  # in [0, 1] across the filter support
        if kind == "box":
            f = np.ones_like(x)
        elif kind == "gaussian":
            # Cycles' Gaussian: exp(−2 (6 v / (3 w))²) for offsets v in ±1.5 w, i.e.
            # exp(−72 (x − ½)²) across the support whatever the width (σ = w/4).
            f = np.exp(-72.0 * (x - 0.5) ** 2)
        else:
            a = 2.0 * np.pi * x
            f = 0.35875 - 0.48829 * np.cos(a) + 0.14128 * np.cos(2 * a) - 0.01168 * np.cos(3 * a)
        f = np.maximum(f, 0.0)
        cdf = np.concatenate([[0.0], np.cumsum(f)])
        self._cdf = cdf / cdf[-1]
        self._grid = np.linspace(0.0, 1.0, self.TABLE + 1)
        # The same inverse tabulated at uniform u, so sampling is an index computation instead of
        # a binary search (measured: camera rays 180 → 54 ns per lane). Between two nodes it is
        # the same linear function unless a CDF node (a kink) lies inside the cell: u in those
        # cells (at most TABLE + 1 of INVERSE_TABLE) takes the binary search, so it stays exact.
        m = self.INVERSE_TABLE
        self._inverse = np.interp(np.linspace(0.0, 1.0, m + 1), self._cdf, self._grid)
        pos = self._cdf * m
        cell = np.minimum(np.floor(pos).astype(np.int64), m - 1)
        self._kinked = np.zeros(m, dtype=np.bool_)
        self._kinked[cell[pos != np.floor(pos)]] = True

    INVERSE_TABLE = 1 << 14

    def tables(self):
        """What the camera kernel needs (kernels/camera.py PixelFilterTable)."""
        from .kernels.camera import PixelFilterTable
        return PixelFilterTable(self._cdf, self._grid, self._inverse, self._kinked, float(self.support))

    def sample(self, u: np.ndarray) -> np.ndarray:
        """u (n, 2) uniform in [0, 1) → pixel-centre offsets (n, 2) in pixels (the renderer's own
        per-lane inversion, backend/kernels/camera.py)."""
        from .kernels.camera import filter_batch
        u = np.ascontiguousarray(u, dtype=np.float64)
        out = np.empty(u.shape)
        filter_batch(*self.tables(), u, out)
        return out


def parse_filter(node: Node | None) -> PixelFilter:
    if node is None:
        return PixelFilter()
    kind = node.string("type", "blackman-harris", choices=("blackman-harris", "gaussian", "box"))
    width = node.number("width", 1.0 if kind == "box" else 1.5, lo=0.01, hi=10)
    node.finish()
    return PixelFilter(kind, width)


class FilmAccumulator:
    """Per-pixel float64 sums, merged from work items in a fixed order (bit-reproducible)."""

    def __init__(self, width: int, height: int, passes=None):
        self.width, self.height = width, height
        n = width * height
        # Data passes (backend/passes.py): sample-0 values and sums; zero columns when none.
        self.passes = passes if passes is not None and passes.active else None
        nf = self.passes.first if self.passes else 0
        self.first = np.zeros((n, nf))
        self.pass_sum = np.zeros((n, (self.passes.width - nf) if self.passes else 0))
        self.sum = np.zeros((n, 3))
        self.sum_sq = np.zeros((n, 3))
        self.albedo = np.zeros((n, 3))
        self.normal = np.zeros((n, 3))
        self.count = np.zeros(n, dtype=np.int64)
        self.alpha = np.zeros(n)
        # Light-traced caustics (kernels/caustics.py): the photons' splats, summed, and how many
        # photons were traced; the image is the samples' mean plus this sum over the photons.
        self.caustic = np.zeros((n, 3))
        self.photons = 0
        self.transparent = False   # set from the scene: alpha = coverage instead of 1

    def add(self, pixels: np.ndarray, result: dict) -> int:
        """Add a work item's per-lane samples (``result["lanes"]``: radiance, albedo, normal,
        alpha; ``result["spp"]`` samples per pixel, lanes of a pixel adjacent). Returns the number
        of non-finite samples dropped. Sample by sample, so the image does not depend on how the
        work was cut (kernels/film.py)."""
        from .kernels.film import accumulate, add_splats
        L, albedo, normal, alpha = result["lanes"]
        caustics = result.get("caustics")
        if caustics is not None:
            photons, pix, rgb = caustics
            self.photons += int(photons)
            add_splats(self.caustic, np.ascontiguousarray(pix, np.int64), np.ascontiguousarray(rgb, np.float64))
        aux = result.get("passes")
        if aux is None or self.passes is None:
            aux = NO_LANES
        return int(accumulate(self.sum, self.sum_sq, self.albedo, self.normal, self.alpha, self.count,
                              self.first, self.pass_sum, np.ascontiguousarray(pixels, np.int64),
                              int(result["spp"]), L, albedo, normal, alpha, aux))

    def _mean(self, a: np.ndarray) -> np.ndarray:
        c = np.maximum(self.count, 1)[:, None]
        return (a / c).reshape(self.height, self.width, -1)

    def combined(self) -> np.ndarray:
        """The image: the camera samples' mean, plus the light-traced caustics where any."""
        img = self._mean(self.sum)
        if self.photons:
            img += (self.caustic / self.photons).reshape(self.height, self.width, 3)
        return img

    def variance_of_mean(self) -> np.ndarray:
        """Unbiased sample variance divided by n, per channel (0 where n < 2):
        max(Σx² − Σx·x̄, 0) / (n (n − 1)). Three full-size temporaries (the written-out form had
        nine: 0.14-0.5 s for a 1024² film, now a third of that)."""
        n = self.count[:, None].astype(np.float64)
        var = self.sum * (self.sum / np.maximum(n, 1.0))
        np.subtract(self.sum_sq, var, out=var)
        np.maximum(var, 0.0, out=var)
        var *= np.where(n >= 2, 1.0 / np.maximum(n * (n - 1.0), 1.0), 0.0)
        return var.reshape(self.height, self.width, 3)

    def albedo_image(self) -> np.ndarray:
        return self._mean(self.albedo)

    def normal_image(self) -> np.ndarray:
        """The mean normal, renormalised (0 where it is 0); scaled in place by one per-pixel
        factor (linalg.norm and two wheres were 0.09 s for a 1024² film)."""
        n = self._mean(self.normal)
        length = np.sqrt(np.einsum("...i,...i->...", n, n))
        n *= np.where(length > 0, 1.0 / np.where(length > 0, length, 1.0), 0.0)[..., None]
        return n

    def coverage(self) -> np.ndarray:
        """Fraction of camera samples that hit a surface (not the world, not a holdout)."""
        return (self.alpha / np.maximum(self.count, 1)).reshape(self.height, self.width)

    def counts(self) -> np.ndarray:
        return self.count.reshape(self.height, self.width)

    def pass_images(self) -> dict:
        """The requested data passes: {EXR pass name: (H, W, C)} (empty when none)."""
        if self.passes is None:
            return {}
        return self.passes.images(self.first, self.pass_sum, self.count, self.height, self.width)

