"""Colour matching after quilting (our addition to TGHop, on by default): run as the last step of
:func:`tghop.generation.synthesize` where the patch refinement does not run (large images: region by
region, :mod:`tghop.regions`; a material's maps: :mod:`tghop.material`).

Generated textures lose contrast and colour saturation: cluster models pull samples
towards their means, and quilting prefers smooth patches because they match any overlap
best. Matching each channel's histogram of the result to the exemplar's (Heeger & Bergen
1995) restores them. On six textures of ``../shared/textures`` it halved the median SIFID,
Gram, SWD and co-occurrence distances while raising novelty (see docs/choices.md).
Switch it off (``match_colours=False``, CLI ``--no-match-colours``) to reproduce the
paper exactly.
"""

from __future__ import annotations

import numpy as np

from ._arrays import check_int, check_mask
from ._errors import TGHopError
from ._estimator import BaseEstimator, ImageInputMixin, StoredArrays, check_is_fitted
from ._images import check_image, checked_image
from ._resources import usable_cores

__all__ = ["channel_quantiles", "match_histograms", "N_QUANTILES", "ColourClasses", "colour_classes", "class_labels",
           "class_quantiles", "class_separation", "class_shares", "mixed_quantiles", "share_spread"]

#: Quantile levels stored per channel (0, 1/256, ..., 1).
N_QUANTILES = 257


def channel_quantiles(image, n: int = N_QUANTILES) -> np.ndarray:
    """Quantiles of each channel of an image.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Float in [0, 1], or uint8 (0 to 255, read as in [0, 1]).
    n : int
        Number of equally spaced probability levels from 0 to 1 (at least 2).

    Returns
    -------
    ndarray, shape (C, n)
    """
    image = checked_image(image, "channel_quantiles", empty=False)
    n = check_int(n, "n", 2, where="channel_quantiles")
    if image.dtype.kind == "u" and image.dtype != np.uint8:
        image = check_image(image, name="channel_quantiles: image", channels=None)
    return _channel_quantiles(image, int(n))


def _channel_quantiles(image, n):
    """:func:`channel_quantiles` of an (H, W, C) array of any values, unchecked."""
    probs = np.linspace(0.0, 1.0, n)
    if image.dtype == np.uint8:  # from the histogram: no float copy of a large exemplar
        out = np.empty((image.shape[2], n))
        for c in range(image.shape[2]):
            hist = np.bincount(image[..., c].ravel(), minlength=256)
            ends = np.cumsum(hist)  # order statistics k < ends[v] have value v
            pos = probs * (ends[-1] - 1)  # numpy's default (linear) quantile positions
            lo = np.floor(pos).astype(np.int64)
            hi = np.minimum(lo + 1, ends[-1] - 1)
            vlo = np.searchsorted(ends, lo, side="right")
            vhi = np.searchsorted(ends, hi, side="right")
            out[c] = (vlo + (pos - lo) * (vhi - vlo)) / 255.0
        return out
    flat = np.asarray(image, dtype=np.float64).reshape(-1, image.shape[2])
    return np.quantile(flat, probs, axis=0).T


#: Resolution of the rank computation: values are binned to 1/65535 (finer than 16-bit).
RANK_BINS = 65536

# Values per step of :func:`match_histograms`, and the images from which it runs a thread
# per channel.
_CHUNK = 1 << 16
_THREADED_PIXELS = 512 * 512


def match_histograms(image, quantiles, *, out=None) -> np.ndarray:
    """Give each channel of ``image`` the distribution described by ``quantiles``.

    Each pixel's rank within its channel (its value binned to 1/65535, mid-rank within a
    bin) is mapped through the target quantile function with linear interpolation: a
    monotone, deterministic map in linear time and small extra memory.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Values in [0, 1] (uint8: 0 to 255, scaled to [0, 1]).
    quantiles : ndarray, shape (C, n)
        From :func:`channel_quantiles` of the reference.
    out : ndarray, shape (H, W, C), optional
        Where to write the result (may be ``image`` itself, to match in place): float64
        by default; a float32 ``out`` gets the float64 values rounded to float32, a uint8
        one the 8-bit values :func:`tghop.imageio.to_uint8` would make of them (without
        the float image: an 8192x8192 RGB image is 1.6 GB in float64, 0.2 GB in uint8).

    Returns
    -------
    ndarray, shape (H, W, C), in [0, 1] (uint8 ``out``: 0 to 255)
    """
    quantiles = np.asarray(quantiles)
    if quantiles.ndim != 2 or quantiles.shape[1] < 2 or quantiles.dtype.kind not in "fiu":
        raise TGHopError(f"match_histograms: quantiles must be a (C, n) array of numbers, n >= 2, "
                         f"got {quantiles.dtype} of shape {quantiles.shape}")
    if not np.all(np.isfinite(quantiles)):  # NaN made a NaN image without a word
        raise TGHopError("match_histograms: quantiles must be finite numbers (no NaN or infinity)")
    image = checked_image(image, "match_histograms", channels=len(quantiles))
    if image.dtype.kind == "u":
        image = check_image(image, name="match_histograms: image", channels=None)
    h, w, c = image.shape
    if out is None:
        out = np.empty((h, w, c))
    elif out.shape != image.shape or out.dtype not in (np.float64, np.float32, np.uint8):
        raise TGHopError(f"match_histograms: out must be a float64, float32 or uint8 array of shape {image.shape}, "
                         f"got {out.dtype} {out.shape}")
    eight_bit = out.dtype == np.uint8
    levels = np.linspace(0.0, 1.0, quantiles.shape[1])
    rows = max(1, _CHUNK // max(1, w))

    def one(k):
        # A few rows at a time, each step in place: the temporaries stay in cache.
        tmp = np.empty((min(rows, h), w))
        bins = np.empty((h, w), dtype=np.uint16)
        for a in range(0, h, rows):
            t = tmp[: min(rows, h - a)]
            np.multiply(image[a : a + rows, :, k], RANK_BINS - 1, out=t, dtype=np.float64)  # float32 images too
            t += 0.5
            np.clip(t, 0, RANK_BINS - 1, out=t)
            bins[a : a + rows] = t  # truncation: t >= 0
        counts = np.bincount(bins.ravel(), minlength=RANK_BINS)
        mid_rank = (np.cumsum(counts) - 0.5 * counts) / bins.size
        table = np.clip(np.interp(mid_rank, levels, quantiles[k]), 0.0, 1.0)
        if eight_bit:  # to_uint8 of each table entry: to_uint8 of every pixel, in one lookup
            table = np.round(table * 255.0).astype(np.uint8)
            tmp = np.empty(tmp.shape, dtype=np.uint8)
        for a in range(0, h, rows):
            t = tmp[: min(rows, h - a)]
            # mode "clip": no bounds check that raises (uint16 bins always index the table),
            # which NumPy does slowly for indices that are not intp.
            np.take(table, bins[a : a + rows], out=t, mode="clip")
            out[a : a + rows, :, k] = t

    # Large images: a thread per channel (NumPy lets go of the interpreter lock in these
    # steps), each channel in chunks whose temporaries stay in cache; the same numbers as
    # whole-channel steps (measured: docs/choices.md).
    if c > 1 and h * w >= _THREADED_PIXELS and usable_cores() > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=c) as pool:
            list(pool.map(one, range(c)))  # a channel's error is raised here
    else:
        for k in range(c):
            one(k)
    return out


# ------------------------------------------------------------------ colour classes
# A 256x256 output of an exemplar with a few distinct colours (stripes, tiles and joints,
# bricks and mortar) rarely holds them in the exemplar's proportions. Matching its whole
# histogram to the exemplar's then turns the brightest pixels of a colour it has too much of
# into the next colour up: white flecks in grey stripes, blue ones in grey. The exemplar's
# colours are therefore split into a few classes, each with its own quantiles; the target
# histogram of an image is the mixture of the classes' histograms in proportions between the
# exemplar's and the image's own (:func:`mixed_quantiles`; docs/choices.md, Colour matching).

#: Pixels the class centres are fitted on (a strided subset beyond this).
_CENTRE_PIXELS = 1 << 14
#: Pixels an exemplar's class quantiles and an image's shares are measured on.
CLASS_PIXELS = 1 << 16


def _strided(pixels, n):
    """At most about ``n`` rows of ``pixels`` (every k-th): the same subset every time."""
    return pixels[:: max(1, len(pixels) // n)]


def colour_classes(pixels, n_classes, *, n_iter=30) -> np.ndarray:
    """Centres of ``n_classes`` classes of colours (Lloyd's K-means, deterministic).

    Parameters
    ----------
    pixels : ndarray, shape (n, C)
        Values in [0, 1].
    n_classes : int
    n_iter : int
        Lloyd steps at most (it stops when no label changes).

    Returns
    -------
    ndarray, shape (n_classes, C)
        Started at the pixels at evenly spaced quantiles of their first principal axis, so
        that no random draw is needed; sorted along that axis, from dark to bright.
    """
    x = np.ascontiguousarray(_strided(np.asarray(pixels), _CENTRE_PIXELS), dtype=np.float64)
    if len(x) < n_classes:
        raise TGHopError(f"colour classes: {len(x)} pixels for {n_classes} classes")
    centred = x - x.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    axis = -axis if axis.sum() < 0 else axis  # from dark to bright
    order = np.argsort(centred @ axis, kind="stable")
    centres = x[order[((np.arange(n_classes) + 0.5) * len(x) / n_classes).astype(int)]]
    labels = None
    for _ in range(n_iter):
        new = class_labels(x, centres)
        if labels is not None and np.array_equal(new, labels):
            break
        labels = new
        for k in range(n_classes):
            members = x[labels == k]
            if len(members):  # an empty class keeps its centre
                centres[k] = members.mean(axis=0)
    return centres[np.argsort((centres - x.mean(axis=0)) @ axis, kind="stable")]


def _squared_distances(pixels, centres) -> np.ndarray:
    """(n, K) squared distances of ``pixels`` (n, C) to ``centres`` (K, C), channel by
    channel (an (n, C) x (C, K) matrix product with C and K this small is many times slower
    in BLAS)."""
    pixels = np.asarray(pixels)
    d = np.zeros((len(pixels), len(centres)))
    for ch in range(pixels.shape[1]):
        d += (pixels[:, ch, None] - centres[None, :, ch]) ** 2
    return d


def class_labels(pixels, centres) -> np.ndarray:
    """The nearest centre of each pixel: (n,) int of ``pixels`` (n, C).

    Parameters
    ----------
    pixels : array_like, shape (n, C)
        Colours, float in [0, 1].
    centres : ndarray, shape (K, C)
        Class centres (:attr:`ColourClasses.centres_`).

    Returns
    -------
    ndarray of int, shape (n,)
        Each pixel's class in ``[0, K)`` (Euclidean distance; ties: the first centre).
    """
    return np.argmin(_squared_distances(pixels, centres), axis=1)


def class_quantiles(values, labels, n_classes, n: int = N_QUANTILES) -> np.ndarray:
    """Quantiles of ``values`` (m, C) within each class of ``labels`` (m,): (n_classes, C, n).
    A class without values gets the quantiles of all of them.

    Parameters
    ----------
    values : array_like, shape (m, C)
        At least one row (read as float64).
    labels : ndarray of int, shape (m,)
        Each row's class (:func:`class_labels`).
    n_classes : int
    n : int
        Quantiles per channel, at evenly spaced levels from 0 to 1.

    Returns
    -------
    ndarray of float64, shape (n_classes, C, n)
    """
    values = np.asarray(values, dtype=np.float64)[:, None, :]  # (m, 1, C): an image, for channel_quantiles
    members = [values[labels == k] for k in range(n_classes)]
    return np.stack([_channel_quantiles(m if len(m) else values, n) for m in members])


#: Margins below which a pixel is near the boundary of its class (:func:`class_separation`), and the
#: share of such pixels in separate colours (at most: separation 1) and in a continuum (at least: 0).
_NEAR_MARGIN = 0.2
_SEPARATE, _CONTINUOUS = 0.05, 0.15


def class_separation(pixels, centres) -> float:
    """How distinct the colour classes of ``pixels`` (n, C) are, from 0 to 1.

    A pixel's margin is ``(d2 - d1) / (d2 + d1)`` for its distances to the nearest and the
    second nearest centre. Cutting a continuum (a uniform or normal distribution) into
    classes leaves about 15 % of the pixels within a margin of 0.2 (a uniform one in four
    classes: 15 %); separate colours (stripes, tiles and their joints) leave few. The
    separation goes linearly from 1, at 5 % of the pixels or fewer, to 0 at 15 % or more.

    Parameters
    ----------
    pixels : array_like, shape (n, C)
        Colours, float in [0, 1].
    centres : ndarray, shape (K, C)

    Returns
    -------
    float
        In [0, 1]; 0 for fewer than two centres.
    """
    if len(centres) < 2:
        return 0.0
    d = _squared_distances(np.asarray(pixels, dtype=np.float64), centres)
    d = np.sqrt(np.partition(d, 1, axis=1)[:, :2])
    near = np.mean((d[:, 1] - d[:, 0]) < _NEAR_MARGIN * (d[:, 1] + d[:, 0]))
    return float(np.clip((_CONTINUOUS - near) / (_CONTINUOUS - _SEPARATE), 0.0, 1.0))


#: Pixels :func:`share_spread` labels: a strided grid of the exemplar beyond this.
_SPREAD_PIXELS = 1 << 18
#: Crop positions per axis of :func:`share_spread` at most (every position below).
_SPREAD_POSITIONS = 64


def share_spread(image, centres, exclude=None) -> np.ndarray:
    """How much the class shares vary between crops of ``image`` (H, W, C) of half its
    shorter side: (K + 1,), each class's standard deviation over the crops, then the crops'
    side (a share's spread in an image of side L is about the crops' times side / L).

    The crops start at every position, or at up to 64 evenly spaced ones per axis: a
    sparse grid of them can fall in step with a periodic exemplar (a stripe's period) and
    find every crop alike. Pixels are labelled once, on a strided grid of at most about
    262,144 of them, and each crop's shares are read from summed-area tables. With
    ``exclude`` (H, W) bool, a sample mask, each crop's shares are those of its pixels
    outside the mask, and crops with less than half of theirs outside are left out; fewer
    than two left: no spread (zeros), so images keep the exemplar's shares.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Float in [0, 1], or uint8 (divided by 255).
    centres : ndarray, shape (K, C)
    exclude : array_like of bool, shape (H, W), optional
        True: left out.

    Returns
    -------
    ndarray of float64, shape (K + 1,)
        Each class's standard deviation of its share over the crops, then the crops' side in
        pixels; all zeros (the side too) when fewer than two crops count.
    """
    h, w = image.shape[:2]
    side = max(1, min(h, w) // 2)
    k = max(1, int(np.ceil(np.sqrt(h * w / _SPREAD_PIXELS))))  # the labelling grid's stride
    grid = np.asarray(image)[::k, ::k]
    gh, gw = grid.shape[:2]
    pixels = np.asarray(grid.reshape(-1, grid.shape[-1]), dtype=np.float64)
    if grid.dtype == np.uint8:
        pixels /= 255.0
    labels = class_labels(pixels, centres).reshape(gh, gw)
    keep = np.ones((gh, gw), dtype=bool) if exclude is None else ~np.asarray(exclude, dtype=bool)[::k, ::k]
    counts = np.zeros((gh + 1, gw + 1, len(centres) + 1))  # summed-area tables: each class, then pixels kept
    counts[1:, 1:, :-1] = (labels[..., None] == np.arange(len(centres))) & keep[..., None]
    counts[1:, 1:, -1] = keep
    counts.cumsum(axis=0, out=counts)
    counts.cumsum(axis=1, out=counts)
    s = max(1, -(-side // k))  # the crop's side on the grid
    ys, xs = (np.unique(np.linspace(0, n - s, min(n - s + 1, _SPREAD_POSITIONS)).round().astype(int))
              for n in (gh, gw))
    y0, x0 = ys[:, None], xs[None, :]
    sums = counts[y0 + s, x0 + s] - counts[y0, x0 + s] - counts[y0 + s, x0] + counts[y0, x0]
    sums = sums.reshape(-1, len(centres) + 1)
    sums = sums[2 * sums[:, -1] >= s * s]  # crops with at least half their pixels kept
    if len(sums) < 2:
        return np.zeros(len(centres) + 1)
    return np.append(np.std(sums[:, :-1] / sums[:, -1:], axis=0), side)


def class_shares(image, centres) -> np.ndarray:
    """The share of each colour class among the pixels of ``image`` (H, W, C) (counted on a
    strided subset of about 65,536 of them): (K,), summing to 1.

    Parameters
    ----------
    image : array_like, shape (H, W, C)
        Float in [0, 1], or uint8 (divided by 255).
    centres : ndarray, shape (K, C)

    Returns
    -------
    ndarray of float64, shape (K,)
    """
    image = np.asarray(image)
    pixels = np.ascontiguousarray(_strided(image.reshape(-1, image.shape[-1]), CLASS_PIXELS), dtype=np.float64)
    if image.dtype == np.uint8:
        pixels /= 255.0
    counts = np.bincount(class_labels(pixels, centres), minlength=len(centres))
    return counts / counts.sum()


def mixed_quantiles(class_q, shares) -> np.ndarray:
    """Quantiles of the mixture of the classes' distributions in proportions ``shares``.

    Parameters
    ----------
    class_q : ndarray, shape (K, C, n)
        Each class's quantiles (:func:`class_quantiles`), read as piecewise linear
        quantile functions.
    shares : ndarray, shape (K,)
        Non-negative, summing to 1.

    Returns
    -------
    ndarray, shape (C, n)
        At the same levels; with the exemplar's own shares, close to its overall quantiles.
    """
    k, c, n = class_q.shape
    levels = np.linspace(0.0, 1.0, n)
    out = np.empty((c, n))
    for ch in range(c):
        # (np.unique would import numpy.ma, which generation does not need otherwise.)
        grid = np.sort(class_q[:, ch], axis=None)
        grid = grid[np.r_[True, np.diff(grid) > 0]]
        cdf = np.zeros(len(grid))
        for q, share in zip(class_q[:, ch], shares):
            if share > 0:
                cdf += share * np.interp(grid, q, levels, left=0.0, right=1.0)
        first = np.r_[True, np.diff(cdf) > 0]  # strictly increasing, to invert
        out[ch] = np.interp(levels, cdf[first], grid[first]) if first.sum() > 1 else grid[0]
    return out


class ColourClasses(ImageInputMixin, StoredArrays, BaseEstimator):
    """The exemplar's colours in a few classes, each with its own histograms (ours).

    Parameters
    ----------
    n_classes : int, default=4

    Attributes
    ----------
    centres_ : ndarray, shape (n_classes, C)
        Class centres (:func:`colour_classes`); a pixel belongs to the nearest.
    shares_ : ndarray, shape (n_classes,)
        The exemplar's share of each class.
    quantiles_ : ndarray, shape (n_classes, C, 257)
        Each class's quantiles of each colour channel (the colour matching's targets).
    refine_quantiles_ : ndarray, shape (n_classes, C, 257)
        The same of the refinement's decorrelated channels (:mod:`tghop.refine`).
    separation_ : ndarray, shape (1,)
        How distinct the classes are (:func:`class_separation`): 1 for separate colours
        (stripes, tiles and joints), 0 for a continuum cut into classes.
    spread_ : ndarray, shape (n_classes + 1,)
        How much the shares vary between the exemplar's own crops (:func:`share_spread`):
        each class's standard deviation, then the crops' side.
    """

    def __init__(self, n_classes=4):
        self.n_classes = n_classes

    def fit(self, image, bands, *, exclude=None):
        """Fit on ``image`` (H, W, C) in [0, 1], without the pixels where ``exclude`` (H, W)
        is true; ``bands``: the fitted :class:`tghop.refine.BandStatistics` (its colour
        axes). Measured on a strided subset of about 65,536 pixels. Returns self.

        Parameters
        ----------
        image : ndarray, shape (H, W, C)
            Float in [0, 1], or uint8 / uint16; C the channels ``bands`` was fitted on.
        bands : tghop.refine.BandStatistics
            Fitted on the same exemplar.
        exclude : array_like of bool, shape (H, W), optional
            True: left out.

        Returns
        -------
        self
        """
        k = self.n_classes
        k = check_int(k, "n_classes", where="ColourClasses")
        check_is_fitted(bands, "colour_mean_")
        image = checked_image(image, "ColourClasses.fit", channels=len(bands.colour_mean_))
        if image.dtype.kind == "u" and image.dtype != np.uint8:
            image = check_image(image, name="ColourClasses.fit: image", channels=None)
        exclude = check_mask(exclude, image.shape, "ColourClasses.fit")
        pixels = (image if exclude is None else image[~exclude]).reshape(-1, image.shape[-1])
        pixels = np.ascontiguousarray(_strided(pixels, CLASS_PIXELS), dtype=np.float64)
        if image.dtype == np.uint8:  # a large exemplar (TGHop.fit keeps it 8-bit): its pixels x / 255
            pixels /= 255.0
        k = int(self.n_classes)
        self.centres_ = colour_classes(pixels, k)
        labels = class_labels(pixels, self.centres_)
        self.shares_ = np.bincount(labels, minlength=k) / len(labels)
        self.quantiles_ = class_quantiles(pixels, labels, k)
        self.refine_quantiles_ = class_quantiles(bands.to_decorrelated(pixels), labels, k)
        self.separation_ = np.array([class_separation(pixels, self.centres_)])
        self.spread_ = share_spread(image, self.centres_, exclude)
        return self

    def targets(self, image, *, own_shares=1.0):
        """The histograms to give ``image`` (H, W, C): the classes' mixed in shares moved
        ``own_shares`` times the classes' separation of the way from the exemplar's towards
        the image's own (a continuum cut into classes keeps the exemplar's histograms: there
        the shares are the image's tone, which matching should correct).

        Parameters
        ----------
        image : ndarray, shape (H, W, C)
            Float in [0, 1] (or uint8), C the exemplar's.
        own_shares : float
            How far towards the image's own shares (0: the exemplar's; 1: the full way the
            separation allows). Each share moves at most two standard deviations of the exemplar's
            own crops, scaled to the image's size.

        Returns
        -------
        (ndarray, ndarray), shapes (C, 257) and (C, 257)
            Quantiles of the refinement's decorrelated channels and of the colours.
        """
        weight = self.weight(own_shares)
        image = checked_image(image, "ColourClasses.targets", channels=self.centres_.shape[1])
        # As far as samples of the exemplar of the image's size would differ (two standard
        # deviations; a share's spread falls as one over the side): a layout's variation, not
        # a blur's bias (docs/choices.md, Colour matching, "Colour classes").
        h, w = np.shape(image)[:2]
        reach = 2.0 * self.spread_[:-1] * self.spread_[-1] / np.sqrt(h * w)
        moved = np.clip(class_shares(image, self.centres_) - self.shares_, -reach, reach)
        shares = np.clip(self.shares_ + weight * moved, 0.0, None)
        shares /= shares.sum()
        return mixed_quantiles(self.refine_quantiles_, shares), mixed_quantiles(self.quantiles_, shares)

    def weight(self, own_shares) -> float:
        """How far :meth:`targets` moves the shares towards an image's own: ``own_shares``
        times the separation (0: the exemplar's histograms, which a model without classes
        matches; :meth:`tghop.synthesis.TGHop.synthesize` then uses those).

        Parameters
        ----------
        own_shares : float
            The setting (:meth:`targets`); not checked.

        Returns
        -------
        float
            ``own_shares * separation_[0]``. Before :meth:`fit`, :class:`~tghop.NotFittedError`.
        """
        check_is_fitted(self, "centres_")
        return float(own_shares) * float(self.separation_[0])

    _ARRAYS = (("colour.centres", "centres_"), ("colour.shares", "shares_"),
               ("colour.class_quantiles", "quantiles_"), ("refine.class_quantiles", "refine_quantiles_"),
               ("colour.separation", "separation_"), ("colour.share_spread", "spread_"))

    def _array_specs(self, c):
        """The arrays of ``c`` colour channels, for the checks of :mod:`tghop.modelfile`."""
        k = int(self.n_classes)
        says = f"the metadata says {k} colour classes of {c} channels"
        return (("colour.centres", (k, c), "f", says, (("range", 0.0, 1.0),)),
                ("colour.shares", (k,), "f", says, (("range", 0.0, 1.0), ("sum", 1.0, 1e-6))),
                ("colour.class_quantiles", (k, c, "Qc"), "f", says, (("range", 0.0, 1.0), ("nondecreasing",))),
                ("refine.class_quantiles", (k, c, "Qc"), "f", says, (("nondecreasing",),)),
                ("colour.separation", (1,), "f", says, (("range", 0.0, 1.0),)),
                ("colour.share_spread", (k + 1,), "f", says, (("range", 0.0, None),)))
