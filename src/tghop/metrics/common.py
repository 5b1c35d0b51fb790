"""What the metrics share: checking a pair of images, progress, patch sizes and samples (what every stage of
the library shares is in :mod:`tghop._images` and :mod:`tghop._progress`; the commands, :mod:`tghop.cli.common`)."""

from __future__ import annotations


import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .._arrays import check_int
from .._errors import TGHopError
from .._images import check_image, grey_as_rgb
from ..exemplar import drop_alpha
from .._progress import report

__all__ = ["PLAIN_MAX_PIXELS", "pair", "without_alpha", "counter", "check_patch_size", "check_seed", "sample_patches",
           "exemplar_statistics"]


#: Images up to this many pixels (512 x 512) are scored in one piece by :func:`sifid` and
#: :func:`cooccurrence_distance`, exactly as before; larger ones in full-width row strips of
#: about this many pixels, so the memory stays bounded (the same score up to float
#: rounding: both are sums over pixels, accumulated strip by strip).
PLAIN_MAX_PIXELS = 512 * 512

def pair(exemplar, result, *, min_size: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Validate two images and give them the same number of channels: two grey images one
    channel each, however they are stored (a grey PNG or an RGB one scores alike), grey and
    colour three each.

    Parameters
    ----------
    exemplar, result : array_like, shape (H, W) or (H, W, C), C in {1, 3}
        Float in [0, 1], or uint8 / uint16 (rescaled); the two sizes may differ. C of 2 or 4: grey or
        RGB with alpha, the alpha dropped with a warning (:func:`without_alpha`).
    min_size : int
        Smallest height and width accepted (a smaller image: :class:`~tghop.InvalidImageError`).

    Returns
    -------
    exemplar, result : ndarray, shape (H, W, C), float64 in [0, 1]
        The same C for both: 1 when both are grey, else 3.
    """
    ex = check_image(without_alpha(exemplar, "exemplar"), min_size=min_size, name="exemplar")
    res = check_image(without_alpha(result, "result"), min_size=min_size, name="result")
    if ex.shape[2] != 1 or res.shape[2] != 1:
        if all(a.shape[2] == 1 or grey_as_rgb(a) for a in (ex, res)):
            ex, res = ex[..., :1], res[..., :1]
        elif ex.shape[2] != res.shape[2]:
            ex, res = (np.repeat(a, 3, axis=2) if a.shape[2] == 1 else a for a in (ex, res))
    return ex, res



def without_alpha(image, name: str):
    """An image a metric scores without its alpha channel: an array of 2 or 4 channels is grey or RGB with
    alpha, dropped with the warnings of :meth:`tghop.TGHop.fit` (:func:`tghop.exemplar.drop_alpha`:
    :class:`~tghop.OpaqueAlphaWarning`, or :class:`~tghop.TransparencyWarning` with its share), as ``tghop
    evaluate`` reads an image file with alpha (0.59; 0.58 refused such an array). ``name``: the image's, in the
    warning."""
    return drop_alpha(image, name=name, exclude=None, keep=None)


#: kind -> (key, value): the statistics of the last exemplar each metric computed (:func:`exemplar_statistics`).
_LAST_EXEMPLAR: dict = {}


def exemplar_statistics(kind: str, image: np.ndarray, options: tuple, compute, units: int = 0, tick=None):
    """``compute()``, or what it gave for the same exemplar and options the last time.

    Scoring many results against one exemplar (``tghop evaluate ex r1 ... r100``) computed the
    exemplar's side of :func:`~tghop.metrics.sifid`, :func:`~tghop.metrics.gram_distance` and
    :func:`~tghop.metrics.cooccurrence_distance` (its Inception moments, Gram matrix, colour
    clusters and co-occurrences) again for every result: half the work of those metrics. The
    last one of each ``kind`` is kept, keyed by ``image``'s shape, dtype and a hash of its bytes
    and by ``options``: the same values, not recomputed. Only statistics are kept, never images
    (the largest, the Gram matrix: 0.5 MB at the defaults); the values returned must not be
    modified. Hashing the exemplar's bytes costs far less than any of these statistics.

    Parameters
    ----------
    kind : str
        The metric (one entry each).
    image : ndarray
        The exemplar as the metric sees it (after :func:`pair`).
    options : tuple
        Whatever else the statistics depend on (hashable).
    compute : callable
        ``compute()`` gives the statistics, calling ``tick`` ``units`` times on its way.
    units, tick
        When the statistics are reused, ``tick()`` is called ``units`` times, so that the
        progress counts the same units either way.

    Returns
    -------
    object
        What ``compute()`` returned.
    """
    import hashlib

    data = np.ascontiguousarray(image)
    key = (data.shape, data.dtype.str, hashlib.blake2b(data.view(np.uint8).ravel(), digest_size=16).digest(),
           options)
    last = _LAST_EXEMPLAR.get(kind)
    if last is not None and last[0] == key:
        for _ in range(units if tick is not None else 0):
            tick()
        return last[1]
    value = compute()
    _LAST_EXEMPLAR[kind] = (key, value)
    return value


def counter(progress, stage: str, total: int):
    """A ``tick()`` that reports ``stage`` one unit further each call (out of ``total``).

    Parameters
    ----------
    progress : callable or None
        ``progress(stage, done, total)``; called once with ``done`` 0 at once.
    stage : str
    total : int

    Returns
    -------
    callable
        ``tick()``, taking no argument; ``done`` stops at ``total``.
    """
    done = [0]
    report(progress, stage, 0, total)

    def tick():
        done[0] += 1
        report(progress, stage, min(done[0], total), total)

    return tick


def check_patch_size(patch_size) -> int:
    """``patch_size`` as a positive int, or a one-line :class:`TGHopError`.

    Parameters
    ----------
    patch_size : int
        A Python or NumPy integer (a bool or a float, even a whole one, is refused).

    Returns
    -------
    int
    """
    return check_int(patch_size, "patch_size", 1)


def check_seed(seed) -> int:
    """A metric's ``seed`` as a non-negative int, or a one-line :class:`TGHopError`.

    The metrics take a fixed integer seed, not a ``numpy.random.Generator``: their samples
    (patches, projections, random filters) are then the same for every result scored with
    the same seed, so that the scores compare.

    Parameters
    ----------
    seed : int

    Returns
    -------
    int
        At least 0.
    """
    if isinstance(seed, np.random.Generator):
        raise TGHopError("seed must be an int, not a Generator: a metric draws its samples from a fixed seed, "
                         "so that scores of different results compare; give e.g. seed=0")
    return check_int(seed, "seed", 0)


def sample_patches(img: np.ndarray, patch_size: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` random stride-1 patches of ``img`` (all, in raster order, if ``n`` is the total).

    Parameters
    ----------
    img : ndarray, shape (H, W, C)
        H and W at least ``patch_size``.
    patch_size : int
    n : int
        Patches wanted; at least the number of positions gives every one.
    rng : numpy.random.Generator
        Draws the positions (without replacement) when ``n`` is below their number.

    Returns
    -------
    ndarray, shape (min(n, (H - P + 1)(W - P + 1)), C * P * P), ``img``'s dtype
        Each patch flattened channel first (C, P, P), P = ``patch_size``.
    """
    windows = sliding_window_view(img, (patch_size, patch_size), axis=(0, 1))  # (nh, nw, C, P, P)
    nh, nw = windows.shape[:2]
    total = nh * nw
    index = np.arange(total) if n >= total else rng.choice(total, size=n, replace=False)
    rows, cols = np.divmod(index, nw)
    return windows[rows, cols].reshape(len(index), -1)
