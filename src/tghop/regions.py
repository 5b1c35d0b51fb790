"""Regional matching: the refinement and the colour matching of a large image, region by region (ours).

The refinement (:mod:`tghop.refine`) and the colour matching (:mod:`tghop.colour`) give
the image the exemplar's histograms, of every band and of every channel. Over a whole large
image that holds on average only: a part a few hundred pixels wide can keep its own
contrast and colour (a dull corner, a yellow one) as long as another part makes up for
it, and a 256x256 crop of a 2048x2048 image then looks less like the exemplar than a
256x256 image does. Matching regions of about ``region`` pixels each separately keeps
every part close to the exemplar. The regions overlap by :data:`OVERLAP` pixels, and their
results are cross-faded there with linear weights that sum to 1, so no region's border
shows.

An image at most about 1.5 regions wide on both sides is matched whole, as before: the
function then only reports that (:func:`n_regions`), and small images are unchanged.
"""

from __future__ import annotations

import numpy as np

from ._errors import TGHopError
from ._images import check_size
from ._progress import ProgressCounter
from ._resources import usable_cores
from .colour import match_histograms
from .refine import prepare as prepare_refinement, refine as refine_bands

__all__ = ["OVERLAP", "n_regions", "region_spans", "prepare", "match_regions"]

#: Pixels by which neighbouring regions overlap (their cross-fade): regions of 1,024 pixels
#: are refined on at most 1,088 pixels a side.
OVERLAP = 64


def _count(n: int, region: int) -> int:
    return max(1, round(n / region))


def n_regions(size, region, *, tile=False) -> tuple:
    """Regions along each axis of an image of ``size`` (H, W): ``round(side / region)``, at
    least 1; (1, 1) for ``region`` None, and in tileable images unless both axes have
    several (a single region along one axis would have to wrap around on its own).

    Parameters
    ----------
    size : int or (int, int)
        The image's (H, W) (no pixel limit).
    region : int or None
        The regions' side in pixels.
    tile : bool
        Whether the image is tileable.

    Returns
    -------
    (int, int)
        Regions along the rows and along the columns.
    """
    h, w = check_size(size, limit=None)
    if region is None:
        return 1, 1
    out = _count(h, region), _count(w, region)
    return (1, 1) if tile and min(out) == 1 else out


def region_spans(n: int, count: int, *, periodic: bool = False, overlap: int = OVERLAP) -> list:
    """The ``count`` overlapping spans of an axis of ``n`` pixels and their weights.

    The axis is cut at ``round(i * n / count)``; each span reaches ``overlap // 2`` pixels
    past its cuts, and its weight rises linearly from 0 to 1 across the overlap at its
    start and falls at its end, so that the weights of all spans sum to 1 at every pixel.
    Periodic axes (tileable images) are cut at 0 as well: the first span starts before 0,
    and its indices wrap around.

    Parameters
    ----------
    n : int
        The axis' length.
    count : int
        Spans wanted (1: the whole axis, weight 1).
    periodic : bool
        Whether the axis wraps around (a tileable image's).
    overlap : int
        Pixels shared by neighbouring spans; a span narrower than it raises :class:`~tghop.TGHopError`.

    Returns
    -------
    list of (int, ndarray of float32, shape (L,))
        Each span's first index (negative for a wrapping one) and its weights.
    """
    if count == 1:
        return [(0, np.ones(n, dtype=np.float32))]
    cuts = [round(i * n / count) for i in range(count + 1)]
    if min(np.diff(cuts)) < overlap:
        raise TGHopError(f"regions of {min(np.diff(cuts))} pixels are narrower than their overlap ({overlap})")
    half = overlap // 2
    ramp = ((np.arange(overlap) + 0.5) / overlap).astype(np.float32)
    spans = []
    for i in range(count):
        ramp_in, ramp_out = periodic or i > 0, periodic or i < count - 1
        start = cuts[i] - half if ramp_in else 0
        stop = cuts[i + 1] + overlap - half if ramp_out else n
        weights = np.ones(stop - start, dtype=np.float32)
        if ramp_in:
            weights[:overlap] = ramp
        if ramp_out:
            weights[-overlap:] = ramp[::-1]
        spans.append((start, weights))
    return spans


def _index(start: int, length: int, n: int):
    """A slice where the span lies inside the axis; wrapped indices otherwise."""
    if 0 <= start and start + length <= n:
        return slice(start, start + length)
    return np.arange(start, start + length) % n


def prepare(size, bands, *, region, tile=False):
    """:func:`tghop.refine.prepare` for the regions of an image of ``size`` (their first
    region's shape; the whole image's where it is one region).

    Parameters
    ----------
    size : int or (int, int)
        The image's (H, W).
    bands : tghop.refine.BandStatistics
        The refinement's statistics.
    region : int or None
        The regions' side in pixels (:func:`n_regions`).
    tile : bool
        Whether the image is tileable.
    """
    h, w = check_size(size, limit=None)
    counts = n_regions((h, w), region, tile=tile)
    shape = [len(region_spans(n, k, periodic=tile)[0][1]) for n, k in zip((h, w), counts)]
    prepare_refinement(tuple(shape), bands)


def match_regions(image, *, bands=None, colour_quantiles=None, pixel_quantiles=None, n_iter=5, region=1024, tile=False,
                  progress=None) -> np.ndarray:
    """Refine and colour-match ``image`` region by region, cross-fading the regions.

    Parameters
    ----------
    image : ndarray, shape (H, W, C), in [0, 1]
        Not changed.
    bands : tghop.refine.BandStatistics, optional
        The refinement's statistics (None: no refinement).
    colour_quantiles : ndarray, shape (C, n), optional
        The colour matching's (:func:`tghop.colour.match_histograms`; None: none).
    pixel_quantiles : ndarray, shape (C, n), optional
        The refinement's pixel targets (``pixel_quantiles`` of :func:`tghop.refine.refine`).
    n_iter : int
        Rounds of the refinement.
    region : int
        Side of a region in pixels, at least ``4 * OVERLAP`` (:func:`n_regions`).
    tile : bool
        The image wraps around: so do the regions at its borders.
    progress : callable, optional
        ``progress("refine", done, total)``: after each round of a region's refinement (the
        refinement's own reports for an image of one region) and as each region is added.

    Returns
    -------
    ndarray, shape (H, W, C), float32, in [0, 1]
    """
    image = np.asarray(image)
    if region < 4 * OVERLAP:
        raise TGHopError(f"region must be at least {4 * OVERLAP} pixels, got {region}")
    h, w, _ = image.shape
    counts = n_regions((h, w), region, tile=tile)
    whole = counts == (1, 1)
    rows, cols = (region_spans(n, k, periodic=tile and not whole) for n, k in zip((h, w), counts))
    spans = [(y, wy, x, wx) for y, wy in rows for x, wx in cols]

    def matched(span, threads=None, progress=None):
        y, wy, x, wx = span
        part = image[_index(y, len(wy), h)][:, _index(x, len(wx), w)].astype(np.float32)  # a copy
        if bands is not None and n_iter:
            part = refine_bands(part, bands, n_iter=n_iter, tile=tile and whole, dtype=np.float32, threads=threads,
                                pixel_quantiles=pixel_quantiles, progress=progress)
        if colour_quantiles is not None:
            part = match_histograms(part, colour_quantiles, out=part)
        return part

    if whole:
        return matched(spans[0], progress=progress)
    out = np.zeros(image.shape, dtype=np.float32)
    # Each region counts its refinement's rounds (channels x rounds, told from the thread that refines it:
    # a large region's rounds take a while) and one step more when it is added here.
    steps = (image.shape[2] * n_iter if bands is not None else 0) + 1
    advance = ProgressCounter(progress, "refine", len(spans) * steps)
    advance(0)
    # A region per core, each refining its channels one after another: regions one at a
    # time with their channels in threads kept the cores less busy (docs/choices.md).
    # The regions are added in a fixed order: the same numbers on any number of cores.
    cores = min(usable_cores(), len(spans))
    from concurrent.futures import ThreadPoolExecutor  # here: an image of one region needs none (it imports logging)

    def one(span, threads=None):
        return matched(span, threads=threads, progress=None if progress is None else advance.relay())

    with ThreadPoolExecutor(max_workers=cores) as pool:
        results = pool.map(lambda span: one(span, threads=1), spans) if cores > 1 else map(one, spans)
        try:
            for (y, wy, x, wx), part in zip(spans, results):
                part *= wy[:, None, None]
                part *= wx[None, :, None]
                ys, xs = _index(y, len(wy), h), _index(x, len(wx), w)
                if isinstance(ys, slice) and isinstance(xs, slice):
                    out[ys, xs] += part
                else:
                    out[np.ix_(np.arange(h)[ys], np.arange(w)[xs])] += part
                advance(1)
        except BaseException:  # a region failed, or progress raised (a job cancelled): the regions waiting
            pool.shutdown(wait=False, cancel_futures=True)  # do not start (the pool's end waited for all of them)
            raise
    return out
