"""Refinement after stitching: match the exemplar's multi-scale statistics (our addition).

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
"""

from __future__ import annotations

import functools
import math
import numbers

import numpy as np

from ._arrays import check_int, check_mask
from ._common import (BaseEstimator, InvalidImageError, StoredArrays, TGHopError, check_image, check_is_fitted,
                      check_size, checked_image, report, usable_cores)
from ._fft import fft_for
from .patches import clean_windows
from .pyramid import laplacian_pyramid, reconstruct

__all__ = ["BandStatistics", "refine", "prepare", "oriented_parts", "iter_oriented_parts", "tail_quantiles",
           "tailed_band_quantiles", "match_quantiles", "RELAXATION", "TAIL_LEVELS"]

#: Side of the largest region :meth:`BandStatistics.fit` measures at once (larger exemplars:
#: up to four crops of this size), so that fitting memory does not grow with the exemplar.
_FIT_SIDE = 1024

#: Values ranked to make a band's matching map, and used to estimate an exemplar band's
#: quantiles at fit time (a strided subset beyond this).
_MAX_VALUES = 1 << 16

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


#: Levels :func:`tail_quantiles` adds inside each end step of a band's quantiles: the end
#: step's share of the values (1/256 of them with 257 quantiles) halved this many times,
#: down to one value in 65,536 (docs/choices.md, Refinement, "Exponential tails (0.42)").
TAIL_LEVELS = 8

#: Entries of the lookup table that applies a matching map (uniform steps over the band's
#: range; each value takes the nearest entry, whose rank among the values gives its new
#: value): a quarter of the values matched, within these bounds (docs/choices.md).
_LUT_MIN, _LUT_MAX = 4096, 1 << 16
# Values mapped per step of a table lookup (the temporaries of one step fit in L2 cache).
_MATCH_CHUNK = 1 << 16


def _crops(h, w, side):
    """``(y, x, height, width)`` of the regions :meth:`BandStatistics.fit` measures: the whole
    image when both sides are at most ``side``, else up to 2 x 2 crops of at most
    ``side x side`` spread evenly over it (first and last rows and columns included)."""
    ch, cw = min(h, side), min(w, side)
    ys = sorted({0, h - ch}) if h > side else [0]
    xs = sorted({0, w - cw}) if w > side else [0]
    return [(y, x, ch, cw) for y in ys for x in xs]


def _subset(values, n_crops):
    """A strided subset of ``values`` (flattened), so that ``n_crops`` crops together keep
    about _MAX_VALUES values (what :func:`_quantiles` would use of one image)."""
    values = values.ravel()
    limit = max(1, _MAX_VALUES // n_crops)
    return values[:: -(-values.size // limit)] if values.size > limit else values


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


def _quantiles(values, levels):
    """Quantiles at ``levels`` of ``values`` (of a strided subset of at most _MAX_VALUES)."""
    return _sample_quantiles(_subset(values, 1), levels)


def _sample_quantiles(sample, levels):
    """Quantiles at ``levels`` of the values in ``sample``."""
    # Sorted in the values' own dtype, then widened: the same numbers, and NumPy's SIMD sort
    # of float32 is faster than of float64 (twice as many values per SIMD register).
    ordered = np.sort(sample).astype(np.float64)
    return np.interp(levels * (ordered.size - 1), np.arange(ordered.size), ordered)


def match_quantiles(values, target, levels, out=None):
    """Monotone map of ``values`` giving them the quantiles ``target`` (at ``levels``).

    Parameters
    ----------
    values : ndarray, any shape
        float32 or float64.
    target : ndarray, shape (L,)
        Non-decreasing quantiles of the distribution to give them.
    levels : ndarray, shape (L,)
        The levels of ``target``, from 0 to 1.
    out : ndarray, optional
        Of ``values``' shape (may be ``values``).

    Returns
    -------
    ndarray, shape of ``values``
        Flat values all map to the target's median.

    Histogram matching by ranks (:func:`_matching`), tabulated at uniform steps over the
    values' range (a quarter as many as values, within _LUT_MIN and _LUT_MAX) and applied
    by looking up the nearest entry: linear time, no sort. When the ranks come from every
    value (at most _MAX_VALUES of them), each value's table entry is found once and used
    for both the ranks and the lookup.
    """
    out = np.empty_like(values) if out is None else out
    src = np.ascontiguousarray(values).reshape(-1)
    dst = out.reshape(-1) if out.flags.c_contiguous else np.empty(out.size, dtype=out.dtype)
    sample = _subset(src, 1)
    if sample.size < src.size:
        _apply_matching(_matching(sample, src.size, target, levels, src.dtype), src, dst)
    else:
        lo, scale, size = _grid(src, src.size)
        if scale is None:
            dst[...] = _flat_value(target, levels)
        else:
            index = _table_index(src, lo, scale, size - 1)
            np.take(_rank_table(index, size, target, levels, src.dtype), index, out=dst, mode="clip")
    if not out.flags.c_contiguous:
        out[...] = dst.reshape(out.shape)
    return out


def tail_quantiles(levels, quantiles, n_tail=TAIL_LEVELS):
    """Quantiles of a band with exponential tails: ``n_tail`` levels added inside each end step.

    Between a band's extreme stored quantile (the exemplar's smallest or largest value there,
    often a lone outlier) and the next lie 1/256 of its values (with 257 quantiles).
    Interpolated linearly, half of them would take values of the outlier's size, which show
    as dark or bright speckles on smooth textures. Band values have exponential tails (a
    Laplacian's), where every halving of the share beyond a quantile moves it by the same
    step: levels ``l1 / 2, l1 / 4, ...`` (``l1``, the second level) take the quantile one,
    two, ... steps ``q1 - q2`` beyond ``q1``, never beyond the extreme one; the upper tail
    likewise.

    Parameters
    ----------
    levels : ndarray, shape (Q,)
        Increasing, from 0 to 1.
    quantiles : ndarray, shape (..., Q)
        Non-decreasing along the last axis, at ``levels``.
    n_tail : int
        Levels added at each end (0: none; nothing is added when Q < 4).

    Returns
    -------
    levels : ndarray, shape (Q + 2 n_tail,)
    quantiles : ndarray, shape (..., Q + 2 n_tail)
    """
    levels, quantiles = np.asarray(levels, dtype=np.float64), np.asarray(quantiles)
    if n_tail == 0 or levels.size < 4:
        return levels, quantiles
    k = np.arange(n_tail, 0, -1)  # the added levels in increasing order: n_tail ... 1 halvings
    low = np.maximum(quantiles[..., :1], quantiles[..., 1:2] - k * (quantiles[..., 2:3] - quantiles[..., 1:2]))
    high = np.minimum(quantiles[..., -1:], quantiles[..., -2:-1] + k[::-1] * (quantiles[..., -2:-1]
                                                                             - quantiles[..., -3:-2]))
    new_levels = np.concatenate([levels[:1], levels[1] * 0.5 ** k, levels[1:-1],
                                 1.0 - (1.0 - levels[-2]) * 0.5 ** k[::-1], levels[-1:]])
    new_quantiles = np.concatenate([quantiles[..., :1], low, quantiles[..., 1:-1], high, quantiles[..., -1:]], axis=-1)
    return new_levels, new_quantiles


def tailed_band_quantiles(band_quantiles):
    """Stored band quantiles (..., Q), at Q evenly spaced levels from 0 to 1, with their
    exponential tails (:func:`tail_quantiles`): ``(levels, quantiles)``, the maps every band
    matching uses."""
    return tail_quantiles(np.linspace(0.0, 1.0, band_quantiles.shape[-1]), band_quantiles)


def _grid(sample, n_values):
    """``(lo, scale, size)`` of the table for ``n_values`` values whose strided subset is
    ``sample``: entry ``i`` stands for ``lo + i / scale``; ``scale`` is None when the
    values are flat (or not finite)."""
    lo, hi = float(np.min(sample)), float(np.max(sample))
    if not hi > lo:
        return lo, None, 0
    size = min(_LUT_MAX, max(_LUT_MIN, n_values // 4))
    return lo, (size - 1) / (hi - lo), size


def _flat_value(target, levels):
    """What flat values map to: the target's median."""
    return float(np.interp(0.5, levels, target))


def _rank_table(index, size, target, levels, dtype):
    """Each table entry's value: the target quantile at the mid-rank of the values that
    take that entry (``index``: their entries).

    A value of rank ``r`` among ``n`` (ties share their middle rank) takes the target's
    quantile at level ``r / (n - 1)``, where NumPy's quantiles put the ``r``-th order
    statistic: the smallest value gets ``target[0]``, the largest ``target[-1]``. Entries
    no value takes lie between their neighbours (the map stays monotone).
    """
    counts = np.bincount(index, minlength=size)
    mid_rank = np.cumsum(counts) - 0.5 * (counts + 1)
    mid_rank *= 1.0 / max(index.size - 1, 1)
    return np.interp(mid_rank, levels, target).astype(dtype)


def _matching(sample, n_values, target, levels, dtype):
    """The map :func:`match_quantiles` applies to ``n_values`` values whose strided subset
    (:func:`_subset`) is ``sample``: ``(lo, scale, table)``, or ``(value, None, None)``
    when the values are flat (all map to one value).

    Histogram matching by ranks: the sample's values are put on the table's grid, counted
    (``bincount``), and each entry takes the target quantile at the mid-rank of its values
    (:func:`_rank_table`), as :func:`tghop.colour.match_histograms` does. That is the
    sample's exact distribution at the table's resolution, in linear time: the quantiles
    of each band used to come from a sort, most of the refinement's time.
    """
    lo, scale, size = _grid(sample, n_values)
    if scale is None:
        return _flat_value(target, levels), None, None
    index = _table_index(sample, lo, scale, size - 1)
    return lo, scale, _rank_table(index, size, target, levels, dtype)


def _apply_matching(matching, src, dst):
    """Apply a :func:`_matching` map to the 1-d array ``src``, into ``dst`` (may be ``src``)."""
    lo, scale, table = matching
    if table is None:
        dst[...] = lo
    else:
        _apply_table(src, lo, scale, table, dst)


def _table_index(src, lo, scale, top, out=None, scratch=None):
    """The nearest table entry of each value of the 1-d array ``src``:
    ``round((src - lo) * scale)`` clipped to ``[0, top]``, as int32 (into ``out``).

    Computed in ``src``'s dtype, _MATCH_CHUNK values at a time (the temporaries stay in
    cache; ``scratch``: a buffer of at least that many values, or of ``src``'s size).
    int32: float32 -> int32 is a SIMD conversion and float32 -> int64 is not.
    """
    dtype = src.dtype
    scale = dtype.type(scale)
    offset = dtype.type(0.5 - lo * float(scale))  # + 0.5: truncation then rounds to nearest
    n = src.size
    out = np.empty(n, dtype=np.int32) if out is None else out
    pos = np.empty(min(_MATCH_CHUNK, n), dtype=dtype) if scratch is None else scratch
    for a in range(0, n, _MATCH_CHUNK):
        e = min(n, a + _MATCH_CHUNK)
        p = pos[: e - a]
        np.multiply(src[a:e], scale, out=p)
        p += offset
        np.clip(p, 0, top, out=p)
        out[a:e] = p  # truncation: p >= 0
    return out


def _apply_table(src, lo, scale, table, dst):
    """``dst = table[round((src - lo) * scale)]``, the index clipped to the table: the
    nearest entry (1-d arrays; ``dst`` may be ``src``).

    _MATCH_CHUNK values at a time, so that the temporaries stay in cache. Four passes,
    against nine for linear interpolation in a table of 4,096 entries, whose largest
    errors were of the same size."""
    n = src.size
    # ``take`` with mode "clip" skips the bounds check that raises (the index is in range
    # already), which NumPy does slowly for indices that are not intp, as these int32 ones.
    idx = np.empty(min(_MATCH_CHUNK, n), dtype=np.int32)
    pos = np.empty(idx.shape, dtype=src.dtype)
    for a in range(0, n, _MATCH_CHUNK):
        e = min(n, a + _MATCH_CHUNK)
        i = _table_index(src[a:e], lo, scale, len(table) - 1, out=idx[: e - a], scratch=pos)
        np.take(table, i, out=dst[a:e], mode="clip")


def _irfft2(fft, spectrum, shape, axes, threads):
    """Inverse of ``rfft2`` over ``axes``; ``spectrum`` is scratch (overwritten).

    With ``scipy.fft``, as its two passes written out (the complex pass along ``axes[0]`` in
    place, then the real pass along ``axes[1]``): ``scipy.fft.irfft2`` copies the spectrum
    first, an extra pass over a large array. The same numbers for
    power-of-two sides, else up to float32 round-off (5e-7).
    """
    if fft is np.fft:
        return np.fft.irfft2(spectrum, s=shape, axes=axes)
    half = fft.ifft(spectrum, axis=axes[0], overwrite_x=True, **threads)
    return fft.irfft(half, n=shape[1], axis=axes[1], overwrite_x=True, **threads)


@functools.lru_cache(maxsize=16)
def _double_angle(h, w, dtype):
    """``cos(2 theta)`` and ``sin(2 theta)`` over the rfft2 grid (``theta``: the frequency's
    direction).

    The oriented windows ``cos^2(theta - k pi / n) * 2 / n`` are
    ``(1 + cos(2 k pi / n) cos(2 theta) + sin(2 k pi / n) sin(2 theta)) / n``, so every part
    is a combination of the band and of its two filtered versions: two inverse transforms
    for any number of orientations. Cached: every round of :func:`refine` and every channel
    uses the same few shapes (the arrays are read-only)."""
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.rfftfreq(w)[None, :]
    # cos 2theta = (fx^2 - fy^2) / r^2 and sin 2theta = 2 fx fy / r^2: no trigonometry
    # (arctan2, cos and sin over a band-sized grid cost far more than these products;
    # made once per shape); the origin counts as theta = 0.
    fx2, fy2 = fx * fx, fy * fy
    r2 = fx2 + fy2
    r2[0, 0] = 1.0
    cos2 = (fx2 - fy2) / r2
    sin2 = (2.0 * fx * fy) / r2
    cos2[0, 0], sin2[0, 0] = 1.0, 0.0
    out = (cos2.astype(dtype), sin2.astype(dtype))
    for m in out:
        m.flags.writeable = False
    return out


def prepare(size, stats):
    """Do ahead of time what refining an image of ``size`` (H, W) first needs: SciPy's FFT
    module loaded for large bands (:func:`tghop._fft.fft_for`) and the oriented windows of every
    band size tabulated. :meth:`tghop.TGHop.synthesize` calls it while
    the coarse guide is made in another thread, so that neither is on the guide's path.
    """
    
    h, w = check_size(size)
    check_is_fitted(stats, "band_quantiles_")
    for _ in range(stats.band_quantiles_.shape[0]):
        if min(h, w) < 2:
            break
        fft_for(h * w)
        if stats.band_quantiles_.shape[1] > 1:
            _double_angle(h, w, np.dtype(np.float32))
        h, w = (h + 1) // 2, (w + 1) // 2


def oriented_parts(band, n_orientations, *, axes=(0, 1)):
    """Split a band into ``n_orientations`` oriented parts that sum to it.

    Part ``k`` keeps the band's spatial frequencies weighted by the angular window
    ``cos^2(theta - k pi / n) * 2 / n`` (steerable-pyramid style, in the Fourier domain,
    periodic boundaries; the windows sum to 1). 0 or 1: the band itself. ``axes``: the
    spatial axes, as in :func:`laplacian_pyramid`.
    """
    return list(iter_oriented_parts(band, n_orientations, axes=axes))


def iter_oriented_parts(band, n_orientations, *, axes=(0, 1), workers=1):
    """:func:`oriented_parts` one part at a time, each a new array the caller may change
    in place (the parts that follow do not depend on it).

    Holding one part at a time instead of all of them keeps about two fewer band-sized
    arrays alive (the refinement of a large band goes further: :func:`_match_oriented`).
    ``workers``: threads of each Fourier transform of a large band (``scipy.fft``; the
    same numbers for any count).
    """
    if n_orientations <= 1:
        yield band
        return
    n = int(n_orientations)
    filtered = _filtered(band, n, axes, workers)
    rest = None  # the sum of the parts so far, in order: p0 + p1 + ...
    for coefs in _part_coefficients(n):
        part = _part(band, filtered, coefs, n)
        if rest is None:
            rest = part.copy()
        else:
            rest += part
        yield part
    # The last part is the rest, so that the parts sum to the band: band - (p0 + p1 + ...).
    del filtered
    yield np.subtract(band, rest, out=rest)


def _part_coefficients(n):
    """``(cos 2 theta_k, sin 2 theta_k)`` of parts ``k = 0 .. n - 2`` (``theta_k = k pi / n``),
    with exact zeros where they vanish (those terms are skipped)."""
    angles = 2.0 * np.pi * np.arange(n - 1) / n
    cos, sin = np.cos(angles), np.sin(angles)
    cos[np.abs(cos) < 1e-12] = 0.0
    sin[np.abs(sin) < 1e-12] = 0.0
    return list(zip(cos.tolist(), sin.tolist()))


def _filtered(band, n, axes, workers):
    """The band filtered by the windows ``cos 2 theta`` (and ``sin 2 theta`` for ``n > 2``):
    every oriented part is ``(band + cos 2 theta_k f_cos + sin 2 theta_k f_sin) / n``."""
    h, w = band.shape[axes[0]], band.shape[axes[1]]
    fft = fft_for(h * w)
    threads = {"workers": int(workers)} if fft is not np.fft else {}
    spectrum = fft.rfft2(band, axes=axes, **threads)  # complex64 for float32 bands (NumPy >= 2, SciPy)
    harmonics = _double_angle(h, w, np.dtype(band.dtype))
    if band.ndim == 3 and tuple(axes) == (0, 1):  # (H, W, C): the windows broadcast over C
        harmonics = [m[..., None] for m in harmonics]
    return [_irfft2(fft, np.multiply(spectrum, m, out=np.empty_like(spectrum) if i == 0 else spectrum),
                    (h, w), axes, threads).astype(band.dtype, copy=False)
            for i, m in enumerate(harmonics[: 1 if n == 2 else 2])]


def _part(band, filtered, coefs, n, out=None):
    """Oriented part ``(band + cos f_cos + sin f_sin) / n`` (``coefs``: :func:`_part_coefficients`
    entry), in this order of operations whatever the slice of the arrays it is given."""
    if out is None:
        part = band.copy()
    else:
        part = out
        np.copyto(part, band)
    for coef, f in zip(coefs, filtered):
        if coef == 1.0:
            part += f
        elif coef == -1.0:
            part -= f
        elif coef:
            part += band.dtype.type(coef) * f
    part *= band.dtype.type(1.0 / n)
    return part


#: Values per step of :func:`_match_oriented` (smaller steps cost more calls; larger
#: ones gain nothing, in threads either; measured: docs/choices.md); bands of at most
#: this many values per channel are matched part by part instead.
_PARTS_CHUNK = 1 << 16


def _match_oriented(band, band_q, levels, *, workers=1):
    """Match every oriented part of a ``(C, H, W)`` band to its quantiles and sum them:
    the band's new value, written into ``band`` (a C-contiguous one; else into a copy) and
    returned.

    What ``for part in iter_oriented_parts(band): match part; sum`` does, with the same
    numbers, but in one pass over the band, _PARTS_CHUNK values at a time: each part's
    map comes from the strided subset of its values (made from the subsets of the band
    and of its filtered versions, with the same operations), then every chunk's parts are
    made, mapped and summed while in cache, without band-sized parts. One channel alone
    (as for very large images, and on one core): faster, as the band is read once. Three
    channels in threads: no faster (the steps are shorter, the threads wait for each
    other more), but the parts no longer take memory, which lowers the peak memory of
    large images (measured: docs/choices.md).

    ``band_q``: ``(n_parts, C, n_quantiles)``.
    """
    n, n_channels = band_q.shape[0], band.shape[0]
    if not band.flags.c_contiguous:  # the channels are worked on as flat views
        band = band.copy()
    if n <= 1:
        for k in range(n_channels):
            match_quantiles(band[k], band_q[0, k], levels, out=band[k])
        return band
    filtered = _filtered(band, n, (1, 2), workers)
    coefs = _part_coefficients(n)
    size = band[0].size
    for k in range(n_channels):
        flat_band = band[k].reshape(-1)  # a view: written in place
        flat_f = [f[k].reshape(-1) for f in filtered]
        # Each part's map, from the strided subsets (the positions _subset takes of the part).
        sub_band = _subset(flat_band, 1)
        sub_f = [_subset(f, 1) for f in flat_f]
        maps = []
        rest = None
        for j, c in enumerate(coefs):
            part = _part(sub_band, sub_f, c, n)
            rest = part.copy() if rest is None else np.add(rest, part, out=rest)
            maps.append(_matching(part, size, band_q[j, k], levels, band.dtype))
        maps.append(_matching(sub_band - rest, size, band_q[n - 1, k], levels, band.dtype))
        # The chunks: parts made, mapped and summed in the order of the loop above.
        chunk = min(size, _PARTS_CHUNK)
        parts = np.empty((n, chunk), dtype=band.dtype)
        for a in range(0, size, chunk):
            e = min(size, a + chunk)
            p = parts[:, : e - a]
            b = flat_band[a:e]
            for j, c in enumerate(coefs):
                _part(b, [f[a:e] for f in flat_f], c, n, out=p[j])
            last = p[n - 1]
            np.copyto(last, p[0])
            for j in range(1, n - 1):
                last += p[j]
            np.subtract(b, last, out=last)
            for j in range(n):
                _apply_matching(maps[j], p[j], p[j])
            total = p[0]
            for j in range(1, n):
                total += p[j]
            b[...] = total
    return band


class BandStatistics(StoredArrays, BaseEstimator):
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

    def fit(self, exemplar, *, exclude=None):
        """Learn from an (H, W, C) exemplar (float in [0, 1], or uint8); returns self.

        Exemplars larger than :data:`_FIT_SIDE` squared are measured on up to four crops of
        that size spread over the image (one at a time, the values pooled), so memory does
        not grow with the exemplar.

        ``exclude`` (H, W) bool, optional: pixels left out (a sample mask). The colour axes
        and pixel quantiles come from the other pixels; excluded pixels are set to the
        mean colour before the pyramid, and each band's values are taken only where no
        excluded pixel lies within a few of that band's pixels (all of them if none is left).
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
                        band_values.setdefault((i, j, k), []).append(_subset(values, len(crops)))
            for k in range(c):
                values = dec[k] if hole is None or hole.all() else dec[k][~hole]
                pixel_values[k].append(_subset(values, len(crops)))
        n_bands = 1 + max((i for i, _, _ in band_values), default=-1)
        self.band_quantiles_ = np.array(
            [[[_quantiles(np.concatenate(band_values[i, j, k]), levels) for k in range(c)]
              for j in range(n_parts)] for i in range(n_bands)]).reshape(n_bands, n_parts, c, self.n_quantiles)
        self.pixel_quantiles_ = np.array([_quantiles(np.concatenate(v), levels) for v in pixel_values])
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
        """(H, W, C) colours -> coordinates on the principal axes (same dtype)."""
        check_is_fitted(self, "colour_mean_")
        img = np.asarray(img)
        mean, basis = (a.astype(img.dtype) for a in (self.colour_mean_, self.colour_basis_))
        return ((img - mean).reshape(-1, img.shape[-1]) @ basis.T).reshape(img.shape)

    def from_decorrelated(self, dec):
        """Inverse of :meth:`to_decorrelated`."""
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
        round (small images: all channels at once; very large ones: one channel at a
        time) or each channel (channels in threads).
    dtype : {numpy.float64, numpy.float32}
        Of the result; the values are computed in float32 either way, so float32 gives
        the same numbers in half the memory.
    threads : int, optional
        At most this many cores (channels in threads, FFT workers; None: every core that
        :func:`~tghop._common.usable_cores` gives). The same numbers either way.
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
    if workers > 1 and cores > 1 and pixels >= _THREADED_PIXELS:
        from concurrent.futures import ThreadPoolExecutor, as_completed

        with ThreadPoolExecutor(max_workers=workers) as pool:
            # Progress is reported from this thread, as channels finish.
            for done, future in enumerate(as_completed([pool.submit(one, k) for k in range(n_channels)]), start=1):
                future.result()
                report(progress, "refine", done * n_iter, total)
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
            one(k, on_round=lambda r, k=k: report(progress, "refine", k * n_iter + r, total), fft_workers=fft_workers)
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
    n_parts, n_channels = band_q.shape[1], band_q.shape[2]
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
            if bands[i][0].size > _PARTS_CHUNK:
                bands[i] = _match_oriented(bands[i], band_q[i], band_lev, workers=fft_workers)
                continue
            # A small band (one chunk): part by part, all channels in each step (fewer calls).
            total = None  # the matched parts summed in order, into the first one
            for j, part in enumerate(iter_oriented_parts(bands[i], n_parts, axes=axes, workers=fft_workers)):
                for k in range(n_channels):
                    match_quantiles(part[k], band_q[i, j, k], band_lev, out=part[k])
                if total is None:
                    total = part
                else:
                    total += part
            bands[i] = total
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
