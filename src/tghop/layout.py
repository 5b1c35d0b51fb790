"""Coarse-to-fine layout: a TGHop model of the exemplar at a coarser scale guides quilting.

32x32 patches cannot hold structures larger than themselves (brick courses, knit cables,
large cells), and quilting alone only matches overlaps, so nothing keeps the arrangement
above the patch scale. :class:`CoarseLayout` fits a second, small TGHop model on the
exemplar downsampled by ``factor`` (box means): its 32x32 patches then cover
``32 * factor`` exemplar pixels. At generation, :meth:`CoarseLayout.guide` quilts a coarse
image from that model (new content, not a copy) and upsamples it to the output size; the
fine level is quilted from the fine model's pool *guided* by it
(:func:`tghop.quilting.quilt` with ``guide``: each candidate's overlap error plus the
distance between its low-pass version and the guide there, Efros & Freeman's texture
transfer).

Example
-------
>>> from tghop import data
>>> from tghop.layout import CoarseLayout
>>> layout = CoarseLayout(factor=2, rng=0).fit(data.bricks())        # doctest: +SKIP
>>> guide = layout.guide((256, 256), rng=1)                           # doctest: +SKIP
"""

from __future__ import annotations

import math
import numbers
import os

import numpy as np
from ._common import BaseEstimator, TGHopError, check_image, check_is_fitted, check_rng, check_size

__all__ = ["CoarseLayout", "downsample", "upsample"]


def downsample(image, factor: int) -> np.ndarray:
    """Box-mean downsampling by an integer ``factor`` (trailing rows/columns dropped).

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Float, or uint8 (0-255).
    factor : int

    Returns
    -------
    ndarray, shape (H // factor, W // factor, C)
        float64, or uint8 (rounded box means) for a uint8 image.
    """
    img = np.asarray(image)
    h, w, c = img.shape
    hs, ws = h // factor, w // factor
    eight_bit = img.dtype == np.uint8
    out = np.empty((hs, ws, c), dtype=np.uint8 if eight_bit else np.float64)
    rows = max(1, (1 << 22) // max(1, factor * ws * factor * c))  # bands of about 4 M values: no whole-image copy
    for y in range(0, hs, rows):
        band = img[y * factor: min(hs, y + rows) * factor, : ws * factor].astype(np.float64)
        mean = band.reshape(-1, factor, ws, factor, c).mean(axis=(1, 3))
        out[y: y + rows] = np.round(mean) if eight_bit else mean
    return out


def upsample(image, factor: int, size, *, wrap: bool = False) -> np.ndarray:
    """Bilinear upsampling by ``factor`` (pixel-centre aligned), cropped to ``size``.

    Parameters
    ----------
    image : ndarray, shape (h, w, C)
    factor : int
    size : (int, int)
        Output (H, W), at most ``(h * factor, w * factor)``.
    wrap : bool
        Treat the image as periodic (for tileable output).

    Returns
    -------
    ndarray, shape (H, W, C), in [0, 1]
        float32 for a float32 image, else float64.
    """
    img = np.asarray(image)
    img = img.astype(np.float32 if img.dtype == np.float32 else np.float64, copy=False)
    h, w = int(size[0]), int(size[1])
    out = np.empty((h, w, *img.shape[2:]), dtype=img.dtype)

    def rows(start, stop):  # output rows [start, stop)
        part = img
        for axis, index in ((0, np.arange(start, stop)), (1, np.arange(w))):
            # Output sample i sits at input coordinate (i + 0.5) / factor - 0.5 (pixel centres).
            pos = (index + 0.5) / factor - 0.5
            lo = np.floor(pos).astype(np.int64)
            frac = (pos - lo).astype(img.dtype).reshape([-1 if a == axis else 1 for a in range(img.ndim)])
            m = img.shape[axis]
            hi = lo + 1
            lo, hi = (np.mod(lo, m), np.mod(hi, m)) if wrap else (np.clip(lo, 0, m - 1), np.clip(hi, 0, m - 1))
            part = (1.0 - frac) * np.take(part, lo, axis=axis) + frac * np.take(part, hi, axis=axis)
        np.clip(part, 0.0, 1.0, out=out[start:stop])

    # A large guide: the two halves of the rows on two threads (a 2048x2048 one is made
    # while the other thread waits for it: 113 -> 65 ms).
    if h * w >= 1 << 20 and h > 1 and (os.cpu_count() or 1) > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=1) as worker:
            lower = worker.submit(rows, h // 2, h)
            rows(0, h // 2)
            lower.result()  # its error, if any, is raised here
    else:
        rows(0, h)
    return out


def _positive_int(value, name, low=1):
    if isinstance(value, bool) or not isinstance(value, (numbers.Integral, np.integer)) or value < low:
        raise TGHopError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


class CoarseLayout(BaseEstimator):
    """A TGHop model of the exemplar downsampled by ``factor``: the layout above patch scale.

    Parameters
    ----------
    factor : int, default=2
        Downsampling of the exemplar (2: coarse patches cover 64x64 exemplar pixels).
    patch_size : int, default=32
        Patch size of the coarse model.
    n_clusters : int, default=50
        ICHM clusters of the coarse model (fewer if it has few training patches: at least
        about 40 patches per cluster).
    min_patches : int, default=2000
        Below this many training patches at stride 2, the coarse model uses stride 1.
    max_patches : int, default=4000
        Training patches of the coarse model (a random subset beyond this): it only needs
        the low-pass layout, so it is kept cheap (with the two settings below, about a
        third of the fine model's fit time).
    cluster_energy, max_cluster_components : float, int, default=0.95, 50
        Per-cluster PCA of the coarse model (the paper's Table 4 values).
    gamma : float, default=0.01
        SDR threshold of the coarse model (the paper's value: the layout needs no fine
        detail, so it keeps the smaller core of the paper, unlike the fine model's 0.003).
    rng : int or numpy.random.Generator, optional

    Attributes
    ----------
    model_ : TGHop
        The coarse model (fitted on the downsampled exemplar).
    """

    def __init__(self, factor=2, patch_size=32, n_clusters=50, min_patches=2000, max_patches=4000,
                 cluster_energy=0.95, max_cluster_components=50, gamma=0.01, rng=None):
        self.factor = factor
        self.patch_size = patch_size
        self.n_clusters = n_clusters
        self.min_patches = min_patches
        self.max_patches = max_patches
        self.cluster_energy = cluster_energy
        self.max_cluster_components = max_cluster_components
        self.gamma = gamma
        self.rng = rng

    def _small_shape(self, shape):
        f = _positive_int(self.factor, "factor", 2)
        return shape[0] // f, shape[1] // f

    def fits(self, shape) -> bool:
        """Whether an exemplar of ``shape`` (H, W, ...) is large enough for this layout."""
        p = _positive_int(self.patch_size, "patch_size", 4)
        return min(self._small_shape(shape)) >= p + p // 2

    def fit(self, image, y=None):
        """Fit the coarse model on ``image`` (H, W, C) downsampled by ``factor``.

        Returns
        -------
        self
        """
        from .synthesis import TGHop  # synthesis imports this module

        img = np.asarray(image)
        if img.dtype != np.uint8:  # uint8 (a large exemplar) is downsampled without a float copy
            img = check_image(image, name="exemplar")
        elif img.ndim == 2:
            img = img[:, :, None]
        f = _positive_int(self.factor, "factor", 2)
        p = _positive_int(self.patch_size, "patch_size", 4)
        hs, ws = self._small_shape(img.shape)
        if min(hs, ws) < p + p // 2:  # at least (p/2 + 1)^2 training patches at stride 1
            raise TGHopError(
                f"a coarse layout at factor {f} needs an exemplar of at least {(p + p // 2) * f}x{(p + p // 2) * f} pixels, "
                f"got {img.shape[0]}x{img.shape[1]}; use a smaller layout factor or none"
            )
        small = downsample(img, f)  # 8-bit stays 8-bit: the coarse fit of a large exemplar costs a byte per value
        count = lambda s: ((hs - p) // s + 1) * ((ws - p) // s + 1)  # noqa: E731
        stride = 2 if count(2) >= self.min_patches else 1
        n_train = min(count(stride), _positive_int(self.max_patches, "max_patches", 100))
        n_clusters = max(2, min(_positive_int(self.n_clusters, "n_clusters", 2), n_train // 40))
        self.model_ = TGHop(
            patch_size=p, stride=stride, n_clusters=n_clusters, cluster_energy=self.cluster_energy,
            max_cluster_components=self.max_cluster_components, gamma=self.gamma, max_patches=n_train,
            layout_factor=None,
            rng=check_rng(self.rng),
        ).fit(small)
        return self

    def guide(self, size, *, rng=None, n_patches=4000, tile=False, refine=3):
        """A coarse synthesis upsampled to ``size``: the layout the fine level follows.

        Parameters
        ----------
        size : (int, int) or int
            Output (H, W).
        rng : int or numpy.random.Generator, optional
        n_patches : int
            Pool of coarse patches.
        tile : bool
            Make the coarse image wrap around (for tileable output).
        refine : int
            Rounds of the refinement after quilting (:mod:`tghop.refine`) of the coarse image
            (at factor 2 without its finest band, which the fine level's comparison by box
            means hardly sees).

        Returns
        -------
        ndarray, shape (H, W, C), float32 in [0, 1]
            (float32: quilting compares it in float32; half the memory of a large guide.)
        """
        check_is_fitted(self, "model_")
        
        f = int(self.factor)
        h, w = check_size(size)
        small = (math.ceil(h / f), math.ceil(w / f))
        if tile and (h % f or w % f):
            raise TGHopError(f"a tileable output with a coarse layout needs a size divisible by {f}, got {h}x{w}")
        p = self.model_.patch_size
        if tile and min(small) < p:
            raise TGHopError(f"a tileable output with a coarse layout at factor {f} needs at least {p * f} pixels a side")
        from .colour import match_histograms
        from .quilting import GUIDE_SCALE
        from .refine import refine as refine_bands

        # What the coarse model's synthesize does, except that the refinement leaves the
        # finest band when the fine level cannot see it: quilting compares the guide by
        # GUIDE_SCALE x GUIDE_SCALE box means, which at factor 2 average 2x2 coarse pixels
        # of the bilinear upsampling and pass at most half of that band (none at its top).
        # Measured on 20 exemplars at 256x256, seeds 0-3: better on 10 of 20 in SIFID, SWD
        # and co-occurrence alike (median changes -0.4 %, -0.2 %, -0.2 %); the guide of a
        # 2048x2048 image 1.37 -> 1.11 s (docs/choices.md).
        coarse = self.model_.synthesize(small, rng=rng, n_patches=n_patches, tile=tile, refine=0, match_colours=False,
                                       dtype=np.float32)
        coarse = refine_bands(coarse, self.model_.bands_, n_iter=refine, tile=tile,  # checks refine too
                              first_level=1 if GUIDE_SCALE // f >= 2 else 0, dtype=np.float32)
        coarse = match_histograms(coarse, self.model_.colour_quantiles_, out=coarse)
        return upsample(coarse, f, (h, w), wrap=tile)
