"""Refinement after stitching: match the exemplar's multi-scale statistics (our addition). This is the band
refinement; the patch refinement is :mod:`tghop.patch_refine`, a hole's :mod:`tghop.hole_refine`, a large
image's, region by region, :mod:`tghop.regions`.

Quilted TGHop images are soft: generated patches lose the contrast of fine detail, and
quilting prefers smooth patches. Heeger & Bergen (1995) synthesise a texture by matching
the histogram of every band of a multi-scale decomposition to the exemplar's; started from
an image that already has the right layout, the same matching restores the contrast of
fine detail at each scale without moving structures or copying exemplar pixels.

The step works in a decorrelated colour space (the principal axes of the exemplar's
colours, as Heeger & Bergen and Portilla & Simoncelli do), decomposes each channel into a
Laplacian pyramid (:mod:`tghop.pyramid`), gives every band the exemplar's distribution (a
monotone map through quantile tables learned at fit time, their tails made exponential:
:func:`tail_quantiles`), rebuilds the image, matches the pixel histogram, and repeats a few
rounds, each but the last over-relaxed (:data:`RELAXATION`).
Everything it needs at generation time is in :class:`BandStatistics` (a few thousand
numbers), so the model file does not keep the exemplar.

Its parts, in their own modules (their public names are imported from here too):

- :mod:`tghop.quantiles`: quantile tables and the matching by rank tables
  (:func:`match_quantiles`, :func:`tail_quantiles`, :func:`tailed_band_quantiles`);
- :mod:`tghop.oriented`: the oriented parts of a band and their matching
  (:func:`oriented_parts`, :func:`iter_oriented_parts`, :func:`tghop.oriented.match_oriented`).

Here: what is learned (:class:`BandStatistics`), the rounds (:func:`refine`) and what they
need ready (:func:`prepare`).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ._arrays import check_int, check_mask
from ._errors import InvalidImageError, TGHopError
from ._estimator import BaseEstimator, ImageInputMixin, StoredArrays, check_is_fitted
from ._images import check_image, check_size, checked_image
from ._progress import ProgressCounter, report
from ._resources import usable_cores
from ._fft import fft_for
from .oriented import double_angle, iter_oriented_parts, match_oriented, oriented_parts, windows_held
from .patches import clean_windows
from .pyramid import laplacian_pyramid, reconstruct
from .quantiles import (TAIL_LEVELS, match_quantiles, strided_subset, tail_quantiles, tailed_band_quantiles,
                        value_quantiles)

__all__ = ["BandStatistics", "refine", "prepare", "oriented_parts", "iter_oriented_parts", "tail_quantiles",
           "tailed_band_quantiles", "match_quantiles", "RELAXATION", "TAIL_LEVELS"]

#: Side of the largest region :meth:`BandStatistics.fit` measures at once (larger exemplars:
#: up to four crops of this size), so that fitting memory does not grow with the exemplar.
_FIT_SIDE = 1024

#: Over-relaxation of the rounds: every round but the last moves the image this many times
#: as far as its matching asks (1: plain Heeger-Bergen rounds); the last round's matching is
#: kept as it is, so the pixels end with the exemplar's distribution (docs/choices.md).
RELAXATION = 1.75

#: Images from this many pixels on are refined with one thread per colour channel.
_THREADED_PIXELS = 512 * 512

#: Working memory of one channel's refinement in image-sized float32 arrays (measured at
#: 4096x4096: the pyramid, the spectrum and the filtered versions of the finest band at once;
#: and the round's starting image, kept to over-relax).
_CHANNEL_ARRAYS = 11
#: The channels refined at the same time use at most about this much working memory
#: together: 3 threads up to about 4096x4096, fewer above (8192x8192: one at a time).
_REFINE_MEMORY = 3 << 30


def _crops(h, w, side):
    """``(y, x, height, width)`` of the regions :meth:`BandStatistics.fit` measures: the whole
    image when both sides are at most ``side``, else up to 2 x 2 crops of at most
    ``side x side`` spread evenly over it (first and last rows and columns included)."""
    ch, cw = min(h, side), min(w, side)
    ys = sorted({0, h - ch}) if h > side else [0]
    xs = sorted({0, w - cw}) if w > side else [0]
    return [(y, x, ch, cw) for y in ys for x in xs]


def _clean_band(hole, level, shape, radius=3):
    """Where band ``level`` (of ``shape``) of an image with excluded pixels ``hole`` (H, W)
    is not reached by them: no excluded pixel within ``radius`` of the band's pixels.
    None when nothing would be left (all values are then used)."""
    step = 2 ** level
    reach = (2 * radius + 1) * step
    padded = np.pad(hole, reach // 2, mode="edge")
    clean = clean_windows(padded, reach)[::step, ::step][: shape[0], : shape[1]]
    if clean.shape != tuple(shape):
        clean = np.pad(clean, [(0, shape[0] - clean.shape[0]), (0, shape[1] - clean.shape[1])])
    return clean if clean.any() else None


def prepare(size, stats):
    """Do ahead of time what refining an image of ``size`` (H, W) first needs: SciPy's FFT
    module loaded for large bands (:func:`tghop._fft.fft_for`) and the oriented windows of every
    band size tabulated (:func:`tghop.oriented.double_angle`). :meth:`tghop.TGHop.synthesize`
    calls it while the coarse guide is made in another thread, so that neither is on the
    guide's path.

    Parameters
    ----------
    size : int or (int, int)
        The (height, width) of the image to be refined (one number: a square).
    stats : BandStatistics
        Fitted; its bands and orientations say which tables are needed.

    Returns
    -------
    None
    """
    h, w = check_size(size)
    check_is_fitted(stats, "band_quantiles_")
    for _ in range(stats.band_quantiles_.shape[0]):
        if min(h, w) < 2:
            break
        fft_for(h * w)
        if stats.band_quantiles_.shape[1] > 1:
            double_angle(h, w, np.dtype(np.float32))
        h, w = (h + 1) // 2, (w + 1) // 2


class BandStatistics(ImageInputMixin, StoredArrays, BaseEstimator):
    """What the refinement learns from the exemplar.

    Parameters
    ----------
    n_levels : int, default=4
        Laplacian bands matched (finest first).
    n_orientations : int, default=4
        Oriented parts per band (0: the Laplacian band as a whole).
    n_quantiles : int, default=257
        Quantile levels per band, orientation and channel.

    Attributes
    ----------
    colour_mean_ : ndarray, shape (C,)
    colour_basis_ : ndarray, shape (C, C)
        Rows: principal axes of the exemplar's colours.
    band_quantiles_ : ndarray, shape (n_levels, max(n_orientations, 1), C, n_quantiles)
        Quantiles of each band (and oriented part) of the exemplar in the decorrelated space.
    pixel_quantiles_ : ndarray, shape (C, n_quantiles)
        Quantiles of the exemplar's pixels in the decorrelated space.
    """

    def __init__(self, n_levels=4, n_orientations=4, n_quantiles=257):
        self.n_levels = n_levels
        self.n_orientations = n_orientations
        self.n_quantiles = n_quantiles

    def fit(self, exemplar, y=None, *, exclude=None):
        """Learn the exemplar's colour axes and its band and pixel distributions.

        Exemplars larger than _FIT_SIDE (1024) squared are measured on up to four crops of
        that size spread over the image (one at a time, the values pooled), so memory does
        not grow with the exemplar.

        Parameters
        ----------
        exemplar : ndarray, shape (H, W, C)
            Float in [0, 1], or uint8 (read as x / 255; uint16 as x / 65535).
        y : None
            Ignored (scikit-learn's signature: a Pipeline passes it; 0.59 took the image alone).
        exclude : array_like of bool, shape (H, W), optional
            Pixels left out (a sample mask). The colour axes and pixel quantiles come from
            the other pixels; excluded pixels are set to the mean colour before the pyramid,
            and each band's values are taken only where no excluded pixel lies within a few of
            that band's pixels (all of them if none is left).

        Returns
        -------
        self
        """
        for name, low in (("n_levels", 0), ("n_orientations", 0), ("n_quantiles", 2)):
            value = getattr(self, name)
            check_int(value, name, low, where="BandStatistics")
        exemplar = checked_image(exemplar, "BandStatistics.fit", "exemplar")
        if exemplar.dtype.kind == "u" and exemplar.dtype != np.uint8:
            exemplar = check_image(exemplar, name="exemplar", channels=None)
        scale = 1.0 / 255.0 if exemplar.dtype == np.uint8 else 1.0
        h, w, c = exemplar.shape
        if h < 1 or w < 1:
            raise InvalidImageError(f"BandStatistics.fit: exemplar is empty ({h}x{w} pixels)")
        exclude = check_mask(exclude, exemplar.shape, "BandStatistics.fit")
        crops = list(_crops(h, w, _FIT_SIDE))
        # Colour axes from a strided subset of at most about a million pixels.
        step = max(1, int(math.ceil(math.sqrt(h * w / 2**20))))
        flat = exemplar[::step, ::step].reshape(-1, c).astype(np.float64) * scale
        if exclude is not None:
            flat = flat[~exclude[::step, ::step].ravel()]
        if len(flat) < 2:  # no covariance of the colours (1x1: NumPy's LinAlgError)
            raise InvalidImageError(f"BandStatistics.fit: the exemplar has {len(flat)} pixel{'s' * (len(flat) != 1)}"
                                    f"{' outside the mask' if exclude is not None else ''}; give at least 2")
        self.colour_mean_ = flat.mean(axis=0)
        cov = np.cov(flat - self.colour_mean_, rowvar=False).reshape(c, c)
        _, vecs = np.linalg.eigh(cov)
        vecs = vecs[:, ::-1]
        vecs *= np.where(vecs.sum(axis=0) < 0, -1.0, 1.0)  # deterministic signs
        self.colour_basis_ = vecs.T
        levels = np.linspace(0.0, 1.0, self.n_quantiles)
        n_parts = max(self.n_orientations, 1)
        band_values, pixel_values = {}, [[] for _ in range(c)]
        for y, x, ch, cw in crops:
            crop = exemplar[y:y + ch, x:x + cw].astype(np.float32) * np.float32(scale)
            dec = np.ascontiguousarray(np.moveaxis(self.to_decorrelated(crop), 2, 0))
            hole = None if exclude is None else exclude[y:y + ch, x:x + cw]
            if hole is not None:
                dec[:, hole] = 0.0  # the mean colour
            bands = laplacian_pyramid(dec, self.n_levels, axes=(1, 2))[:-1]
            for i, b in enumerate(bands):
                keep = None if hole is None else _clean_band(hole, i, b.shape[1:])
                for j, part in enumerate(oriented_parts(b, self.n_orientations, axes=(1, 2))):
                    for k in range(c):
                        values = part[k] if keep is None else part[k][keep]
                        band_values.setdefault((i, j, k), []).append(strided_subset(values, len(crops)))
            for k in range(c):
                values = dec[k] if hole is None or hole.all() else dec[k][~hole]
                pixel_values[k].append(strided_subset(values, len(crops)))
        n_bands = 1 + max((i for i, _, _ in band_values), default=-1)
        self.band_quantiles_ = np.array(
            [[[value_quantiles(np.concatenate(band_values[i, j, k]), levels) for k in range(c)]
              for j in range(n_parts)] for i in range(n_bands)]).reshape(n_bands, n_parts, c, self.n_quantiles)
        self.pixel_quantiles_ = np.array([value_quantiles(np.concatenate(v), levels) for v in pixel_values])
        return self

    #: Fitted arrays in model files: (file name, attribute).
    _ARRAYS = (("refine.colour_mean", "colour_mean_"), ("refine.colour_basis", "colour_basis_"),
               ("refine.band_quantiles", "band_quantiles_"), ("refine.pixel_quantiles", "pixel_quantiles_"))

    def _array_specs(self, c):
        """The arrays of statistics of ``c`` colour channels for the checks of
        :mod:`tghop.modelfile`: ``(name, shape, kind, says, rules)`` each."""
        def orthonormal(arr, dims):
            if np.abs(arr @ arr.T - np.eye(len(arr))).max() > 1e-6:
                return "is not an orthonormal basis"
            return None

        parts = max(int(self.n_orientations), 1)
        return (
            ("refine.colour_mean", (c,), "f", f"the metadata says {c} colour channels", (("range", 0.0, 1.0),)),
            ("refine.colour_basis", (c, c), "f", f"the metadata says {c} colour channels", (orthonormal,)),
            ("refine.band_quantiles", ("L", parts, c, "Q"), "f",
             f"the metadata says at most {self.n_levels} levels of {parts} parts and {c} channels",
             (("dim", 0, 0, self.n_levels), ("dim", 3, 2, None), ("nondecreasing",))),
            ("refine.pixel_quantiles", (c, "Q"), "f", f"the metadata says {c} channels",
             (("dim", 1, 2, None), ("nondecreasing",))),
        )

    def to_decorrelated(self, img):
        """Colours -> coordinates on the principal axes of the exemplar's colours.

        Parameters
        ----------
        img : array_like, shape (H, W, C) (or any (..., C))
            Float colours.

        Returns
        -------
        ndarray, ``img``'s shape and dtype
            ``(img - colour_mean_) @ colour_basis_.T``.
        """
        check_is_fitted(self, "colour_mean_")
        img = np.asarray(img)
        mean, basis = (a.astype(img.dtype) for a in (self.colour_mean_, self.colour_basis_))
        return ((img - mean).reshape(-1, img.shape[-1]) @ basis.T).reshape(img.shape)

    def from_decorrelated(self, dec):
        """Inverse of :meth:`to_decorrelated`: coordinates on the principal axes -> colours.

        Parameters
        ----------
        dec : array_like, shape (H, W, C) (or any (..., C))
            Float coordinates.

        Returns
        -------
        ndarray, ``dec``'s shape and dtype
            ``dec @ colour_basis_ + colour_mean_`` (not clipped).
        """
        check_is_fitted(self, "colour_mean_")
        dec = np.asarray(dec)
        mean, basis = (a.astype(dec.dtype) for a in (self.colour_mean_, self.colour_basis_))
        return ((dec.reshape(-1, dec.shape[-1]) @ basis) + mean).reshape(dec.shape)


def refine(image, stats, *, n_iter=5, tile=False, first_level=0, progress=None, dtype=np.float64, threads=None,
           relaxation=RELAXATION, pixel_quantiles=None):
    """Heeger-Bergen refinement of a synthesised image.

    Each round gives every band (every oriented part of it) of the image's Laplacian
    pyramid, in the exemplar's decorrelated colour space, the exemplar's distribution,
    rebuilds the image and gives its pixels the exemplar's distribution. Monotone maps
    only: the layout stays, the contrast of detail at each scale becomes the exemplar's.

    Parameters
    ----------
    image : ndarray, shape (H, W, C), in [0, 1]
        Refined in float32 (a float32 image is not copied to float64 first); uint8 (0 to 255)
        is scaled to [0, 1].
    stats : BandStatistics
        Fitted on the exemplar (same C).
    n_iter : int
        Rounds (0: the image, clipped).
    tile : bool
        Periodic boundaries (for tileable output).
    first_level : int
        Bands finer than this level keep their values (0: every band is matched). The
        coarse layout's guide leaves its finest band, which the fine level hardly sees
        (:meth:`tghop.synthesis.CoarseLayout.guide`).
    progress : callable, optional
        ``progress("refine", done, total)``, ``total`` = channels x rounds: after each
        round (small images: all channels at once; large ones: of each channel, from the
        channel's thread when the channels run in threads).
    dtype : {numpy.float64, numpy.float32}
        Of the result; the values are computed in float32 either way, so float32 gives
        the same numbers in half the memory.
    threads : int, optional
        At most this many cores (channels in threads, FFT workers; None: every core that
        :func:`~tghop._resources.usable_cores` gives). The same numbers either way.
    relaxation : float
        In (0, 2]: each round but the last moves the image this many times as far as its
        matching asks (:data:`RELAXATION`; 1: plain rounds).
    pixel_quantiles : ndarray, shape (C, n_quantiles), optional
        The decorrelated pixels' target quantiles instead of ``stats.pixel_quantiles_``
        (those of the exemplar's colour classes in an image's shares:
        :meth:`tghop.colour.ColourClasses.targets`).

    Returns
    -------
    ndarray, shape (H, W, C), ``dtype``, in [0, 1]
    """
    for name, value in (("n_iter", n_iter), ("first_level", first_level)):
        check_int(value, name, 0, where="refine")
    if not isinstance(relaxation, numbers.Real) or isinstance(relaxation, bool) or not 0 < relaxation <= 2:
        raise TGHopError(f"refine: relaxation must be a number in (0, 2], got {relaxation!r}")
    check_is_fitted(stats, ("colour_mean_", "band_quantiles_"))
    image = checked_image(image, "refine")
    if image.dtype not in (np.float32, np.float64):  # float32 stays float32: refined in float32 anyway
        image = check_image(image, name="refine: image", channels=None)
    if image.shape[2] != len(stats.colour_mean_):
        raise TGHopError(f"refine: image of shape {image.shape} but the statistics have "
                         f"{len(stats.colour_mean_)} channels")
    dtype = np.dtype(dtype)
    if dtype not in (np.float32, np.float64):
        raise TGHopError(f"refine: dtype must be float32 or float64, got {dtype}")
    if n_iter == 0:
        return np.clip(image.astype(dtype), 0.0, 1.0)
    mode = "wrap" if tile else "reflect"
    # The decorrelated channels are refined independently (each band of each channel has
    # its own quantiles): one thread per channel for large images (NumPy's FFT and
    # element-wise loops release the GIL), even on fewer cores: three channels on two
    # workers would leave one core idle while the last channel runs alone.
    # Memory (a large image): each channel is made once, as its own array, and then
    # belongs to its task alone; the results go back to colours a few rows at a time, so
    # that no stacked copies of all channels are made.
    channels = _decorrelated_channels(stats, image)
    results = [None] * len(channels)
    q = stats.band_quantiles_
    pixel_q = stats.pixel_quantiles_ if pixel_quantiles is None else np.asarray(pixel_quantiles, dtype=np.float64)
    if pixel_q.shape != stats.pixel_quantiles_.shape:
        raise TGHopError(f"refine: pixel_quantiles of shape {pixel_q.shape}, not {stats.pixel_quantiles_.shape}")

    def take(k):  # the channel's only reference moves into _refine_channel, which lets go of it early
        x, channels[k] = channels[k], None
        return x

    def one(k, on_round=None, fft_workers=1):
        results[k] = _refine_channel(take(k), q[:, :, k], pixel_q[k], n_iter=n_iter, mode=mode,
                                     first_level=first_level, on_round=on_round, fft_workers=fft_workers,
                                     relaxation=relaxation)

    n_channels = len(channels)
    total = n_channels * n_iter
    report(progress, "refine", 0, total)
    pixels = image.shape[0] * image.shape[1]
    workers = min(n_channels, max(1, _REFINE_MEMORY // (_CHANNEL_ARRAYS * 4 * pixels)))
    cores = usable_cores() if threads is None else max(1, min(int(threads), usable_cores()))
    with windows_held():  # each band's oriented windows made once a refinement (not a round), whatever their size
        if workers > 1 and cores > 1 and pixels >= _THREADED_PIXELS:
            from concurrent.futures import ThreadPoolExecutor, as_completed

            # Progress: after each round of each channel, from the channel's thread (a channel's rounds of a large
            # image take a while); the counter keeps the counts growing.
            advance = ProgressCounter(progress, "refine", total)
            with ThreadPoolExecutor(max_workers=workers) as pool:
                futures = [pool.submit(one, k, on_round=lambda r: advance(1)) for k in range(n_channels)]
                for future in as_completed(futures):
                    future.result()
        elif pixels < _THREADED_PIXELS:
            # A small image: all channels at once, stacked (one NumPy call per step instead of
            # one per channel, whose call overhead dominates on small arrays; the same
            # numbers).
            stack = np.stack([take(k) for k in range(n_channels)])
            results[:] = _refine_channel(stack, q, pixel_q, n_iter=n_iter, mode=mode,
                                         first_level=first_level, relaxation=relaxation,
                                         on_round=lambda r: report(progress, "refine", r * n_channels, total))
        else:
            # One channel at a time (too large for several at once, or one core): a large
            # image's Fourier transforms then use every core.
            fft_workers = cores
            for k in range(n_channels):
                one(k, on_round=lambda r, k=k: report(progress, "refine", k * n_iter + r, total),
                    fft_workers=fft_workers)
    return _colours(stats, results, dtype)


# Values per step of the colour conversions around the refinement (in cache).
_ROWS_CHUNK = 1 << 16


def _decorrelated_channels(stats, image):
    """:meth:`BandStatistics.to_decorrelated` of an (H, W, C) image in float32, as C
    separate (H, W) arrays, a few rows at a time, so that the temporaries stay in cache
    (the same numbers)."""
    h, w, c = image.shape
    mean, basis = (a.astype(np.float32) for a in (stats.colour_mean_, stats.colour_basis_))
    channels = [np.empty((h, w), dtype=np.float32) for _ in range(c)]
    rows = max(1, _ROWS_CHUNK // w)
    for a in range(0, h, rows):
        block = (image[a : a + rows].astype(np.float32, copy=False) - mean).reshape(-1, c) @ basis.T
        for k in range(c):
            channels[k][a : a + rows] = block[:, k].reshape(-1, w)
    return channels


def _colours(stats, channels, dtype=np.float64):
    """Inverse of :func:`_decorrelated_channels`, clipped to [0, 1]: (H, W, C) ``dtype``
    (computed in float32)."""
    h, w = channels[0].shape
    c = len(channels)
    mean, basis = (a.astype(np.float32) for a in (stats.colour_mean_, stats.colour_basis_))
    out = np.empty((h, w, c), dtype=dtype)
    rows = max(1, _ROWS_CHUNK // w)
    for a in range(0, h, rows):
        block = np.stack([x[a : a + rows] for x in channels], axis=2).reshape(-1, c) @ basis + mean
        out[a : a + rows] = np.clip(block, 0.0, 1.0, out=block).reshape(-1, w, c)
    return out


def _refine_channel(x, band_q, pixel_q, *, n_iter, mode, first_level=0, on_round=None, fft_workers=1,
                    relaxation=1.0):
    """``n_iter`` rounds of band and pixel histogram matching of one (H, W) channel, or of
    several stacked as (C, H, W).

    ``band_q`` (n_levels, n_parts, n_quantiles) and ``pixel_q`` (n_quantiles,) are the
    exemplar's quantiles of this channel (with C channels: (n_levels, n_parts, C,
    n_quantiles) and (C, n_quantiles)); ``on_round(r)`` is called after round r (1, 2,
    ...); ``fft_workers``: threads of each Fourier transform (when the channels run one at
    a time); bands finer than ``first_level`` are not matched; every round but the last
    moves ``x`` ``relaxation`` times as far as its matching asks.
    """
    single = x.ndim == 2
    if single:  # as one channel of a stack: the same numbers
        x, band_q, pixel_q = x[None], band_q[:, :, None], pixel_q[None]
    n_channels = band_q.shape[2]
    qlev = np.linspace(0.0, 1.0, pixel_q.shape[-1])
    band_lev, band_q = tailed_band_quantiles(band_q)
    axes = (1, 2)
    for r in range(1, n_iter + 1):
        bands = laplacian_pyramid(x, len(band_q), mode=mode, axes=axes)
        # The bands hold it now: kept only to over-relax (one band-sized array less otherwise).
        before = x if relaxation != 1 and r < n_iter else None
        x = None
        for i in range(first_level, len(bands) - 1):
            # Every oriented part matched, the matched parts summed: the new band.
            bands[i] = match_oriented(bands[i], band_q[i], band_lev, workers=fft_workers)
        x = reconstruct(bands, mode=mode, axes=axes)
        if before is x:  # no bands: the pyramid is the image itself, matched in place below
            before = x.copy()
        for k in range(n_channels):
            match_quantiles(x[k], pixel_q[k], qlev, out=x[k])
        if before is not None:  # x = before + relaxation (x - before), in place
            x -= before
            x *= relaxation
            x += before
            before = None
        if on_round is not None:
            on_round(r)
    x = x[0] if single else x
    return x
