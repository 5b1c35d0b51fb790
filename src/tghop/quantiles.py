"""Quantile tables and monotone matching by ranks: the distributions :mod:`tghop.refine` learns and gives.

A band's (or a channel's) distribution is stored as its quantiles at evenly spaced levels
(:func:`value_quantiles`, from a strided subset of at most 65,536 values). Giving
values such a distribution is histogram matching by ranks (:func:`match_quantiles`): the
values are put on a table of uniform steps over their range, counted, and each entry takes
the target quantile at the mid-rank of its values (a rank table, linear time, no sort);
each value then takes its nearest entry. :func:`tail_quantiles` gives the stored
quantiles exponential tails, so that a lone outlier of the exemplar does not become many.

Users: the band refinement (:mod:`tghop.refine`, :mod:`tghop.oriented`), and through it the refinement
of a hole (:mod:`tghop.hole_refine`) and every synthesis that refines (guided ones and materials too).
"""

from __future__ import annotations

import numpy as np

__all__ = ["TAIL_LEVELS", "apply_matching", "match_quantiles", "matching_map", "strided_subset", "tail_quantiles",
           "tailed_band_quantiles", "value_quantiles"]


#: Values ranked to make a band's matching map, and used to estimate an exemplar band's
#: quantiles at fit time (a strided subset beyond this).
_MAX_VALUES = 1 << 16

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


def strided_subset(values, n_pooled):
    """A strided subset of ``values``, so that ``n_pooled`` such subsets pooled together keep
    about _MAX_VALUES values (what :func:`value_quantiles` uses of one array).

    Parameters
    ----------
    values : ndarray, any shape
        Flattened (a view where NumPy can).
    n_pooled : int
        How many subsets will be pooled (1: one array's; :meth:`tghop.refine.BandStatistics.fit`
        pools those of up to four crops of a large exemplar).

    Returns
    -------
    ndarray, shape (m,)
        Every ``k``-th value, ``k`` the smallest step leaving at most ``_MAX_VALUES // n_pooled``
        of them (all values when there are no more).
    """
    values = values.ravel()
    limit = max(1, _MAX_VALUES // n_pooled)
    return values[:: -(-values.size // limit)] if values.size > limit else values


def value_quantiles(values, levels):
    """Quantiles at ``levels`` of ``values`` (of a strided subset of at most _MAX_VALUES).

    Parameters
    ----------
    values : ndarray, any shape
        Numbers, flattened; beyond _MAX_VALUES (65,536), a strided subset of them
        (:func:`strided_subset`).
    levels : ndarray, shape (Q,)
        Levels from 0 to 1.

    Returns
    -------
    ndarray, shape (Q,), float64
        NumPy's linear quantiles of the (subset of the) values.
    """
    return _sample_quantiles(strided_subset(values, 1), levels)


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

    Histogram matching by ranks (:func:`matching_map`), tabulated at uniform steps over the
    values' range (a quarter as many as values, within _LUT_MIN and _LUT_MAX) and applied
    by looking up the nearest entry: linear time, no sort. When the ranks come from every
    value (at most _MAX_VALUES of them), each value's table entry is found once and used
    for both the ranks and the lookup.
    """
    out = np.empty_like(values) if out is None else out
    src = np.ascontiguousarray(values).reshape(-1)
    dst = out.reshape(-1) if out.flags.c_contiguous else np.empty(out.size, dtype=out.dtype)
    sample = strided_subset(src, 1)
    if sample.size < src.size:
        apply_matching(matching_map(sample, src.size, target, levels, src.dtype), src, dst)
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
    """Stored band quantiles with their exponential tails (:func:`tail_quantiles`): the maps
    every band matching uses.

    Parameters
    ----------
    band_quantiles : ndarray, shape (..., Q)
        Non-decreasing along the last axis, at Q evenly spaced levels from 0 to 1 (as
        :attr:`tghop.refine.BandStatistics.band_quantiles_` stores them).

    Returns
    -------
    levels : ndarray, shape (Q + 2 TAIL_LEVELS,)
    quantiles : ndarray, shape (..., Q + 2 TAIL_LEVELS)
    """
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


def matching_map(sample, n_values, target, levels, dtype):
    """The map :func:`match_quantiles` applies to ``n_values`` values whose strided subset
    (:func:`strided_subset`) is ``sample``; :func:`apply_matching` applies it.

    Histogram matching by ranks: the sample's values are put on the table's grid, counted
    (``bincount``), and each entry takes the target quantile at the mid-rank of its values
    (:func:`_rank_table`), as :func:`tghop.colour.match_histograms` does. That is the
    sample's exact distribution at the table's resolution, in linear time: the quantiles
    of each band used to come from a sort, most of the refinement's time.

    Parameters
    ----------
    sample : ndarray, shape (m,)
        The strided subset of the values whose ranks make the map.
    n_values : int
        How many values the map is for (the table has a quarter as many entries, within
        _LUT_MIN and _LUT_MAX).
    target : ndarray, shape (L,)
        Non-decreasing quantiles of the distribution to give the values.
    levels : ndarray, shape (L,)
        The levels of ``target``, from 0 to 1.
    dtype : numpy.dtype
        Of the table (the values' dtype).

    Returns
    -------
    tuple
        ``(lo, scale, table)``: entry ``i`` of ``table`` (shape (size,), ``dtype``) is the
        new value of values near ``lo + i / scale``; or ``(value, None, None)`` when the
        values are flat (all map to ``value``, the target's median).
    """
    lo, scale, size = _grid(sample, n_values)
    if scale is None:
        return _flat_value(target, levels), None, None
    index = _table_index(sample, lo, scale, size - 1)
    return lo, scale, _rank_table(index, size, target, levels, dtype)


def apply_matching(matching, src, dst):
    """Apply a :func:`matching_map` map to ``src``, into ``dst``.

    Parameters
    ----------
    matching : tuple
        What :func:`matching_map` returns.
    src : ndarray, shape (n,)
        The values, float32 or float64.
    dst : ndarray, shape (n,)
        Receives the mapped values (may be ``src``).
    """
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
