"""The Laplacian pyramid of the refinement, the inpainting and the patch refinement.

A 5-tap binomial kernel ``(1, 4, 6, 4, 1) / 16``, applied polyphase: each step down blurs
along both spatial axes and keeps every second sample, each step up interpolates back;
a band is an image minus its blurred and re-expanded self, so :func:`reconstruct` gives
the image back exactly (up to rounding). Borders are mirrored, or periodic for tileable
images (``mode="wrap"``). Works on (H, W, C) images and on (C, H, W) stacks (``axes``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["laplacian_pyramid", "reconstruct", "downsample", "upsample"]


def _pad(img, axis, width, mode):
    """``width`` samples added at both ends of ``axis``: periodic ("wrap") or mirrored with
    the edge sample repeated (``np.pad``'s "symmetric"). Slices and one concatenation: a
    refinement pads about 200 times, and ``np.pad``'s own overhead was a fifth of
    refining a 128x128 image."""
    n = img.shape[axis]
    if width > n:  # tiny arrays: np.pad repeats the pattern
        pad = [(0, 0)] * img.ndim
        pad[axis] = (width, width)
        return np.pad(img, pad, mode="wrap" if mode == "wrap" else "symmetric")
    if mode == "wrap":
        head, tail = _take(img, axis, n - width, n), _take(img, axis, 0, width)
    else:
        head, tail = np.flip(_take(img, axis, 0, width), axis), np.flip(_take(img, axis, n - width, n), axis)
    return np.concatenate([head, img, tail], axis=axis)


def _take(img, axis, start, stop, step=1):
    index = [slice(None)] * img.ndim
    index[axis] = slice(start, stop, step)
    return img[tuple(index)]


def _down_axis(img, axis, mode):
    """Blur with the binomial kernel along ``axis`` and keep every second sample."""
    n = img.shape[axis]
    m = (n + 1) // 2
    p = _pad(img, axis, 2, mode)
    taps = [_take(p, axis, t, t + 2 * m - 1, 2) for t in range(5)]
    # (taps0 + taps4 + 4 (taps1 + taps3) + 6 taps2) / 16, in that order, in two arrays.
    out = np.add(taps[0], taps[4])
    tmp = np.add(taps[1], taps[3])
    tmp *= 4.0
    out += tmp
    out += np.multiply(taps[2], 6.0, out=tmp)
    out *= 1.0 / 16.0
    return out


def _up_axis(img, axis, n, mode):
    """Inverse polyphase step: twice as many samples along ``axis`` (``n`` of them)."""
    m = img.shape[axis]
    p = _pad(img, axis, 1, mode)
    left, mid, right = (_take(p, axis, t, t + m) for t in range(3))
    shape = list(img.shape)
    shape[axis] = 2 * m
    out = np.empty(shape, dtype=img.dtype)
    even = [slice(None)] * img.ndim
    odd = [slice(None)] * img.ndim
    even[axis], odd[axis] = slice(0, None, 2), slice(1, None, 2)
    tmp = np.add(left, right)
    tmp += np.multiply(mid, 6.0, out=out[tuple(odd)])  # the odd samples are written last
    np.multiply(tmp, 0.125, out=out[tuple(even)])
    np.add(mid, right, out=tmp)
    np.multiply(tmp, 0.5, out=out[tuple(odd)])
    return _take(out, axis, 0, n)


def _down(img, mode, axes):
    return _down_axis(_down_axis(img, axes[0], mode), axes[1], mode)


def _up(img, shape, mode, axes):
    return _up_axis(_up_axis(img, axes[0], shape[axes[0]], mode), axes[1], shape[axes[1]], mode)


def downsample(img, mode="reflect", axes=(0, 1)):
    """One step down the pyramid of :func:`laplacian_pyramid` (blur, every second sample).

    Parameters
    ----------
    img : ndarray, shape (H, W, C) or (C, H, W)
        Float; ``axes`` are its spatial axes.
    mode : {"reflect", "wrap"}
        Mirrored borders, or periodic ones (tileable images).
    axes : tuple of int
        The spatial axes: (0, 1) for (H, W, C), (1, 2) for (C, H, W).

    Returns
    -------
    ndarray, shape (ceil(H / 2), ceil(W / 2)) along ``axes``, the other axes as ``img``'s
    """
    return _down(img, mode, axes)


def upsample(img, shape, mode="reflect", axes=(0, 1)):
    """One step up (:func:`reconstruct`'s interpolation) to ``shape``.

    Parameters
    ----------
    img : ndarray, shape (h, w, C) or (C, h, w)
        Float; ``axes`` are its spatial axes.
    shape : tuple of int
        The shape to reach (``h`` and ``w`` along ``axes`` are ``ceil`` of half of it).
    mode : {"reflect", "wrap"}
        As :func:`downsample`.
    axes : tuple of int
        As :func:`downsample`.

    Returns
    -------
    ndarray, shape ``shape``, ``img``'s dtype
    """
    return _up(img, shape, mode, axes)


def laplacian_pyramid(img, n_levels, *, mode="reflect", axes=(0, 1)):
    """Bands ``[L0 (finest), ..., L{n-1}, low-pass]`` of an image.

    ``axes`` are the spatial axes: (0, 1) for (H, W, C), (1, 2) for (C, H, W). Fewer
    levels when the image gets smaller than 2 pixels. Exact: :func:`reconstruct`
    returns the image (up to rounding).

    Parameters
    ----------
    img : ndarray, shape (H, W, C) or (C, H, W)
        Float.
    n_levels : int
        Band-pass levels wanted (at most; see above).
    mode : {"reflect", "wrap"}
        As :func:`downsample`.
    axes : tuple of int
        As :func:`downsample`.

    Returns
    -------
    list of ndarray
        Band ``k`` of (about) ``H / 2**k`` x ``W / 2**k`` along ``axes``; the low-pass last.
    """
    bands = []
    cur = img
    for _ in range(n_levels):
        if min(cur.shape[axes[0]], cur.shape[axes[1]]) < 2:
            break
        low = _down(cur, mode, axes)
        bands.append(cur - _up(low, cur.shape, mode, axes))
        cur = low
    bands.append(cur)
    return bands


def reconstruct(bands, *, mode="reflect", axes=(0, 1)):
    """Inverse of :func:`laplacian_pyramid`.

    Parameters
    ----------
    bands : list of ndarray
        As :func:`laplacian_pyramid` returns them (the low-pass last).
    mode : {"reflect", "wrap"}
        The pyramid's.
    axes : tuple of int
        The pyramid's.

    Returns
    -------
    ndarray, shape of ``bands[0]``
        The image (exactly, up to rounding, for an unchanged pyramid).
    """
    cur = bands[-1]
    for band in reversed(bands[:-1]):
        cur = band + _up(cur, band.shape, mode, axes)
    return cur
