"""Oriented parts of a band, and their matching: the orientations of :mod:`tghop.refine`.

A Laplacian band (:mod:`tghop.pyramid`) mixes every direction. Splitting it into ``n``
oriented parts that sum to it (steerable-pyramid style: angular windows
``cos^2(theta - k pi / n) * 2 / n`` in the Fourier domain, :func:`oriented_parts`) lets the
refinement give each direction of each band the exemplar's distribution: bricks' mortar
lines, wood's grain. Every part is a combination of the band and of its two filtered
versions (:func:`double_angle`), so any number of orientations costs two inverse Fourier
transforms per band.

:func:`match_oriented` matches a band's parts to their quantiles (:mod:`tghop.quantiles`)
and sums them: for a large band in one pass a chunk at a time, without band-sized parts.
"""

from __future__ import annotations

import collections
import contextlib
import threading

import numpy as np

from ._fft import fft_for
from .quantiles import apply_matching, match_quantiles, matching_map, strided_subset

__all__ = ["double_angle", "iter_oriented_parts", "match_oriented", "oriented_parts", "MAX_WINDOW_BYTES",
           "WindowsInfo", "windows_held"]

#: The most bytes the oriented windows kept between calls take (:func:`double_angle`'s tables, the least recently
#: used dropped first; 0.58 kept the last 16 band shapes whatever their size). One band's tables take 4 bytes a
#: pixel of the band (float32): 0.26 MB at 256x256, 4.2 MB at 1024x1024, 9.4 MB for a 1535x1535 region's first
#: band (12.6 MB its four), 268 MB for the first band of the largest image (67 Mpx: a tileable strip, refined
#: whole; a large picture's fill), where 16 such shapes held 4.3 GB. While a refinement runs (:func:`windows_held`)
#: the tables it uses stay whatever their size, so that no round makes them again.
MAX_WINDOW_BYTES = 64 * 1024**2

#: :func:`double_angle`'s ``cache_info()``: calls answered from the kept tables, tables made, tables kept, their
#: bytes, and the bound (:data:`MAX_WINDOW_BYTES`).
WindowsInfo = collections.namedtuple("WindowsInfo", "hits misses kept nbytes max_bytes")
_windows: collections.OrderedDict = collections.OrderedDict()  # (h, w, dtype) -> (cos2, sin2), oldest first
_windows_lock = threading.Lock()  # generations on several threads (tghop serve) share the tables
_windows_counts = [0, 0]  # hits, misses
_held: dict = {}  # (h, w, dtype) -> tables, kept while any windows_held block is open (on any thread)
_holding = [0]  # windows_held blocks open


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


@contextlib.contextmanager
def windows_held():
    """While the block runs, :func:`double_angle` keeps every table it gives, whatever its size (then only the
    bound of :data:`MAX_WINDOW_BYTES` holds): around the rounds of one refinement, its channels on any thread
    (:func:`tghop.refine.refine`, :func:`tghop.hole_refine.refine_hole`), so that a band whose tables are over
    the bound has them made once, not once a round and channel. They go when the last block open ends."""
    with _windows_lock:
        _holding[0] += 1
    try:
        yield
    finally:
        with _windows_lock:
            _holding[0] -= 1
            if not _holding[0]:
                _held.clear()


def double_angle(h, w, dtype):
    """``cos(2 theta)`` and ``sin(2 theta)`` over the rfft2 grid (``theta``: the frequency's
    direction).

    The oriented windows ``cos^2(theta - k pi / n) * 2 / n`` are
    ``(1 + cos(2 k pi / n) cos(2 theta) + sin(2 k pi / n) sin(2 theta)) / n``, so every part
    is a combination of the band and of its two filtered versions: two inverse transforms
    for any number of orientations. Kept for the next call: every round of :func:`tghop.refine.refine`
    and every channel uses the same few shapes (:func:`tghop.refine.prepare` makes them ahead); the
    least recently used go first once the tables kept take more than :data:`MAX_WINDOW_BYTES`
    (``double_angle.cache_info()``: :class:`WindowsInfo`; ``double_angle.cache_clear()`` drops them).

    Parameters
    ----------
    h, w : int
        The band's height and width.
    dtype : numpy.dtype
        Of the band (hashable: ``np.dtype(np.float32)``, not the type).

    Returns
    -------
    cos2, sin2 : ndarray, shape (h, w // 2 + 1), ``dtype``
        Read-only; at the origin ``theta`` counts as 0.
    """
    key = (int(h), int(w), np.dtype(dtype))
    with _windows_lock:
        found = _held.get(key, _windows.get(key))
        if key in _windows:
            _windows.move_to_end(key)
        _windows_counts[found is None] += 1
    if found is None:
        found = _double_angle(*key)
        size = found[0].nbytes + found[1].nbytes
        with _windows_lock:
            if size <= MAX_WINDOW_BYTES:
                _windows[key] = found
                while sum(a.nbytes + b.nbytes for a, b in _windows.values()) > MAX_WINDOW_BYTES:
                    _windows.popitem(last=False)
    with _windows_lock:
        if _holding[0]:
            _held[key] = found
    return found


def _windows_info() -> WindowsInfo:
    with _windows_lock:
        return WindowsInfo(*_windows_counts, len(_windows), sum(a.nbytes + b.nbytes for a, b in _windows.values()),
                           MAX_WINDOW_BYTES)


def _windows_clear() -> None:
    with _windows_lock:
        _windows.clear()
        _windows_counts[:] = [0, 0]


double_angle.cache_info = _windows_info
double_angle.cache_clear = _windows_clear


def _double_angle(h, w, dtype):
    """:func:`double_angle`'s tables, made."""
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


def oriented_parts(band, n_orientations, *, axes=(0, 1)):
    """Split a band into ``n_orientations`` oriented parts that sum to it.

    Part ``k`` keeps the band's spatial frequencies weighted by the angular window
    ``cos^2(theta - k pi / n) * 2 / n`` (steerable-pyramid style, in the Fourier domain,
    periodic boundaries; the windows sum to 1).

    Parameters
    ----------
    band : ndarray, shape (H, W), (H, W, C) or (C, H, W)
        float32 or float64, as :func:`tghop.pyramid.laplacian_pyramid` makes it.
    n_orientations : int
        Parts (0 or 1: the band itself).
    axes : (int, int)
        The spatial axes, as in :func:`tghop.pyramid.laplacian_pyramid`.

    Returns
    -------
    list of ndarray, each of ``band``'s shape and dtype
        ``max(n_orientations, 1)`` parts, in order of their angle ``k pi / n``; with 0 or 1,
        ``[band]`` itself.
    """
    return list(iter_oriented_parts(band, n_orientations, axes=axes))


def iter_oriented_parts(band, n_orientations, *, axes=(0, 1), workers=1):
    """:func:`oriented_parts` one part at a time, each a new array the caller may change
    in place (the parts that follow do not depend on it).

    Holding one part at a time instead of all of them keeps about two fewer band-sized
    arrays alive (the refinement of a large band goes further: :func:`match_oriented`).

    Parameters
    ----------
    band, n_orientations, axes
        As :func:`oriented_parts`.
    workers : int
        Threads of each Fourier transform of a large band (``scipy.fft``; the same numbers
        for any count).

    Yields
    ------
    ndarray, ``band``'s shape and dtype
        The parts in :func:`oriented_parts`' order (with 0 or 1 orientations, ``band`` itself).
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
    harmonics = double_angle(h, w, np.dtype(band.dtype))
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
        # Each part's map, from the strided subsets (the positions strided_subset takes of the part).
        sub_band = strided_subset(flat_band, 1)
        sub_f = [strided_subset(f, 1) for f in flat_f]
        maps = []
        rest = None
        for j, c in enumerate(coefs):
            part = _part(sub_band, sub_f, c, n)
            rest = part.copy() if rest is None else np.add(rest, part, out=rest)
            maps.append(matching_map(part, size, band_q[j, k], levels, band.dtype))
        maps.append(matching_map(sub_band - rest, size, band_q[n - 1, k], levels, band.dtype))
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
                apply_matching(maps[j], p[j], p[j])
            total = p[0]
            for j in range(1, n):
                total += p[j]
            b[...] = total
    return band


def match_oriented(band, band_q, levels, *, workers=1):
    """Give every oriented part of a band its quantiles, and sum the matched parts: the band
    the refinement rebuilds its image from (:func:`tghop.refine.refine`).

    A band of more than _PARTS_CHUNK values per channel in one pass, a chunk at a time
    (:func:`_match_oriented`); a smaller one part by part (:func:`iter_oriented_parts`), all
    channels in each step. The same numbers either way.

    Parameters
    ----------
    band : ndarray, shape (C, H, W)
        float32 or float64; may be overwritten.
    band_q : ndarray, shape (n_parts, C, L)
        Each part's and channel's target quantiles (``n_parts``: the orientations, at least 1).
    levels : ndarray, shape (L,)
        Their levels, from 0 to 1 (:func:`tghop.quantiles.tailed_band_quantiles`).
    workers : int
        Threads of each Fourier transform (the same numbers for any count).

    Returns
    -------
    ndarray, shape (C, H, W), ``band``'s dtype
        ``band`` itself or a new array.
    """
    if band[0].size > _PARTS_CHUNK:
        return _match_oriented(band, band_q, levels, workers=workers)
    # A small band (one chunk): part by part, all channels in each step (fewer calls).
    total = None  # the matched parts summed in order, into the first one
    for j, part in enumerate(iter_oriented_parts(band, band_q.shape[0], axes=(1, 2), workers=workers)):
        for k in range(band_q.shape[1]):
            match_quantiles(part[k], band_q[j, k], levels, out=part[k])
        if total is None:
            total = part
        else:
            total += part
    return total
