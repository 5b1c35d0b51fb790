"""How regular a picture is: its strongest repeat within a few patches, from its autocorrelation.

A hole's block is matched on its known pixels within a band of those it fills
(:func:`tghop.inpaint.inpaint`, docs/choices.md, Inpainting "matched in a band"): one overlap for an
irregular texture, whose large elements a wide match fills as blended, faint blocks; a regular one (brick
courses, tiles) keeps its rows only when a block sees a whole period of what is known beside it
(0.62; :func:`match_band`).

The autocorrelation is taken over the known pixels only (the hole's masked out, each lag normalised by the
pairs of known pixels it has): ``r(d)``, 1 at ``d = 0``. Its peaks away from the origin are the repeats; the
strongest, ``r`` at a positive local maximum whose valley towards the origin is at least ``PROMINENCE`` below it,
within ``MAX_LAG`` patch sides (Chebyshev), is the texture's regularity; the nearest peak nearly as strong
(``FUNDAMENTAL``) gives its period.

Example
-------
>>> import numpy as np
>>> from tghop.period import repeat
>>> stripes = np.tile(np.repeat([0.2, 0.8], 8), 8)[None].repeat(96, axis=0)[..., None]   # a period of 16 columns
>>> strength, lag = repeat(stripes, np.zeros((96, 128), bool), 32)
>>> round(strength, 2), lag
(1.0, 16)
"""

from __future__ import annotations

import numpy as np

from ._arrays import check_int, check_mask
from ._errors import TGHopError

__all__ = ["repeat", "match_band", "REGULAR", "PROMINENCE", "FUNDAMENTAL", "MAX_LAG", "MARGIN"]

#: A picture is regular when its strongest repeat correlates at least this much (brick courses 0.39-0.53, tiles
#: and weaves above 0.35; stones, gravel, grass, spots below 0.25: docs/choices.md, Inpainting "0.62").
REGULAR = 0.35

#: A peak counts only where ``r`` falls at least this far below it between it and the origin (else it is the
#: ridge of the origin's own peak, as along grass blades).
PROMINENCE = 0.1

#: The period is the nearest peak of at least this share of the strongest's correlation.
FUNDAMENTAL = 0.8

#: Repeats are looked for up to this many patch sides away (a period above a block's side needs no band).
MAX_LAG = 2

#: The pixels around the hole's bounding box that are read (patch sides).
MARGIN = 4


def _checked(image, hole, patch_size, where):
    """``image`` as an (H, W, C) array (not copied), ``hole`` as bool (H, W) and ``patch_size``, or a one-line
    :class:`TGHopError` naming ``where`` (0.63 raised NumPy's errors, or read a hole of another shape as too few
    pixels; 0.64)."""
    image = np.asarray(image)
    if image.ndim != 3:
        raise TGHopError(f"{where}: image must be an (H, W, C) array, got shape {image.shape}; give a grey picture as "
                         "image[..., None]")
    hole = check_mask(False if hole is None else hole, image.shape, where, "hole")
    return image, hole, check_int(patch_size, "patch_size", where=where)


def _autocorrelation(grey, known, reach):
    """``r`` (2 reach + 1, 2 reach + 1), the origin at the centre, and the pairs of known pixels at each lag."""
    from scipy import fft

    # Padded so that lags up to reach do not wrap around.
    shape = tuple(fft.next_fast_len(n + reach, real=True) for n in grey.shape)
    values = np.where(known, grey - grey[known].mean(), 0.0)
    f, m = fft.rfft2(values, shape), fft.rfft2(known.astype(np.float64), shape)

    def near(spectrum):  # the circular correlation's lags -reach..reach on both axes
        full = fft.irfft2(spectrum, shape)
        return np.roll(full, (reach, reach), axis=(0, 1))[:2 * reach + 1, :2 * reach + 1]

    num, pairs = near(f * np.conj(f)), near(m * np.conj(m))
    var = float(np.square(values[known]).mean())
    return num / np.maximum(pairs, 1.0) / max(var, 1e-12), pairs


def repeat(image, hole, patch_size):
    """The picture's strongest repeat over its known pixels: ``(strength, lag)``.

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Float; the channels are averaged.
    hole : ndarray of bool, shape (H, W)
        Pixels not read.
    patch_size : int
        Repeats are looked for up to :data:`MAX_LAG` times this (Chebyshev distance), from 2 pixels.

    Returns
    -------
    strength : float
        The autocorrelation at the strongest prominent peak (1: the picture repeats exactly; 0 where none is
        found).
    lag : int
        Its Chebyshev distance from the origin in pixels (0 where none is found).
    """
    from scipy.ndimage import maximum_filter

    image, hole, patch_size = _checked(image, hole, patch_size, "repeat")
    known = ~hole
    grey = np.asarray(image, np.float64).mean(axis=2)
    if known.sum() < 4 * patch_size * patch_size or grey[known].std() == 0:
        return 0.0, 0
    reach = min(MAX_LAG * patch_size, grey.shape[0] - 1, grey.shape[1] - 1)
    r, pairs = _autocorrelation(grey, known, reach)
    r = np.where(pairs >= 0.25 * known.sum(), r, -1.0)  # lags with too few pairs are not read
    dy, dx = np.mgrid[-reach:reach + 1, -reach:reach + 1]
    lag = np.maximum(abs(dy), abs(dx))
    peaks = (r == maximum_filter(r, size=5, mode="constant", cval=-1.0)) & (lag >= 2) & (r > -1.0)
    found = []  # (r, lag) of the prominent peaks
    for y, x in zip(*np.nonzero(peaks)):
        k = int(lag[y, x])
        t = np.linspace(0.0, 1.0, 2 * k + 1)
        line = r[np.round(reach + t * dy[y, x]).astype(int), np.round(reach + t * dx[y, x]).astype(int)]
        if r[y, x] > 0 and r[y, x] - line.min() >= PROMINENCE:  # a peak of negative correlation is no repeat
            found.append((float(r[y, x]), k))
    if not found:
        return 0.0, 0
    strength = max(v for v, _ in found)
    # The period: the nearest peak nearly as strong (an exact repeat has equal peaks at its multiples).
    return strength, min(k for v, k in found if v >= FUNDAMENTAL * strength)


def match_band(image, hole, overlap, patch_size):
    """The band of known pixels a hole's block is matched on (:func:`tghop.inpaint.inpaint`, ``order`` "edge").

    Parameters
    ----------
    image : ndarray, shape (H, W, C)
        Float; only the pixels outside ``hole`` within :data:`MARGIN` patch sides of its bounding box are read.
    hole : ndarray of bool, shape (H, W)
    overlap : int
        The band of an irregular picture (0.61's for every picture).
    patch_size : int

    Returns
    -------
    int
        Pixels (8-neighbour steps) from the block's pixels to fill: ``overlap`` where the picture's repeat
        (:func:`repeat`) is weaker than :data:`REGULAR` or the hole is empty, else its period, at least
        ``overlap`` and at most ``patch_size`` (every known pixel of a block).
    """
    image, hole, patch_size = _checked(image, hole, patch_size, "match_band")
    rows, cols = np.flatnonzero(hole.any(axis=1)), np.flatnonzero(hole.any(axis=0))
    if not rows.size:
        return int(overlap)
    m = MARGIN * patch_size
    box = (slice(max(0, rows[0] - m), rows[-1] + 1 + m), slice(max(0, cols[0] - m), cols[-1] + 1 + m))
    strength, lag = repeat(image[box], hole[box], patch_size)
    if strength < REGULAR:
        return int(overlap)
    return int(min(max(lag, overlap), patch_size))
